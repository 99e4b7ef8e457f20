"""The command line's arguments and the files a user passes: each mistake refused with one line
naming it (exit code 2), under the usage of the subcommand that got it.
"""

import pytest

from conftest import CONFIGS, REPO
from pma_model_ros.cli.main import main

MAP = str(REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250_force_map.csv')
SPEC = str(REPO / 'config' / 'muscles' / 'dmsp_10_250.yaml')
CONFIG = str(CONFIGS['DMSP-10-250'])


def _refused(capsys, argv: list[str]) -> tuple[str, str]:
    """The usage's first line and the error line of an argv argparse refuses (exit code 2)."""
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.splitlines()
    return err[0], err[-1]


@pytest.mark.parametrize(
    'argv, option',
    [
        (['fit', '--data', MAP, '--data', MAP, '--muscle', SPEC, '--model', 'martens', '--out',
          'OUT'], '--data'),
        (['force', '--config', CONFIG, '--pressure', '3e5', '--length', '.2', '--length', '.3'],
         '--length'),
        (['bag', 'estimate', 'b', '--config', CONFIG, '--out', 'OUT', '--out', 'OUT'], '--out'),
    ],
)  # fmt: skip
def test_an_option_given_twice_is_refused(tmp_path, capsys, argv, option):
    """Refused before any work (argparse alone keeps the last value without a word)."""
    out = tmp_path / 'out'
    usage, error = _refused(capsys, [str(out) if a == 'OUT' else a for a in argv])
    command = ' '.join(a for a in argv[:2] if not a.startswith('-') and a != 'b')
    assert usage.startswith(f'usage: pma-model {command} ')
    assert error.startswith(f'pma-model {command}: error: argument {option}: given twice (')
    assert not out.exists()


@pytest.mark.parametrize(
    'argv, message',
    [
        (['fit', '--modle', 'martens'], "unknown option --modle (did you mean '--model'?)"),
        (['fit', '--overwite'], "unknown option --overwite (did you mean '--overwrite'?)"),
        (['fit', '--no-calibrate-len'],
         "unknown option --no-calibrate-len (did you mean '--no-calibrate-length'?)"),
        (['force', '--config', CONFIG, '--overwrite'],
         'unknown option --overwrite (pma-model force -h lists its options)'),
        (['bag', 'estimate', 'b', '--confg=x'],
         "unknown option --confg (did you mean '--config'?)"),
    ],
)  # fmt: skip
def test_an_unknown_option_is_named_under_its_subcommand(capsys, argv, message):
    """Named before a missing required option, with the closest option of that subcommand
    (prefixes are not taken: no abbreviations), under that subcommand's usage.
    """
    usage, error = _refused(capsys, argv)
    command = 'bag estimate' if argv[0] == 'bag' else argv[0]
    assert usage.startswith(f'usage: pma-model {command} ')
    assert error == f'pma-model {command}: error: {message}'


def test_an_extra_argument_is_named_under_its_subcommand(capsys):
    argv = ['force', '--config', CONFIG, '--pressure', '3e5', '--length', '0.23', 'extra']
    usage, error = _refused(capsys, argv)
    assert usage.startswith('usage: pma-model force ')
    assert error == 'pma-model force: error: unrecognized arguments: extra'


def test_a_negative_value_is_a_value(capsys):
    """-0.01 after --length-rate is its value, not an unknown option."""
    argv = ['force', '--config', CONFIG, '--pressure', '3e5', '--length', '0.23']
    assert main([*argv, '--length-rate', '-0.01']) == 0
    assert capsys.readouterr().out.startswith('force ')


@pytest.mark.parametrize(
    'config, message',
    [
        ('example_multi_muscle.yaml',
         "a file of several muscles (muscles: ['biceps', 'triceps', 'wrist_flexor', 'finger']), "
         "read whole by model_node and bag estimate; pass one muscle's parameter file (force and "
         'pressure pick one of these with --muscle NAME)'),
        ('example_joint.yaml',
         "a joint file (joints: ['elbow']), read by pma-model joint and joint_node; pass one "
         "muscle's parameter file (its muscles' files, beside it: dmsp_10_250.yaml)"),
    ],
)  # fmt: skip
@pytest.mark.parametrize('command', ['force', 'pressure', 'evaluate'])
def test_a_file_of_another_kind_says_what_it_is(capsys, config, message, command):
    path = REPO / 'config' / config
    value = {'force': ['--pressure', '3e5'], 'pressure': ['--force', '100']}
    query = [*value.get(command, ['--data', MAP]), *(['--length', '0.23'] if value else [])]
    assert main([command, '--config', str(path), *query[: 4 if command != 'evaluate' else 2]]) == 2
    assert capsys.readouterr().err == f'pma-model: error: {path}: {message}\n'


def test_muscle_picks_one_muscle_of_a_multi_muscle_file(capsys):
    """wrist_flexor of the example file is a copy of the shipped DMSP-10-250 file's muscle (the
    file's header): the same force and pressure, printed alike.
    """
    multi = str(REPO / 'config' / 'example_multi_muscle.yaml')
    for query in (['force', '--pressure', '3e5'], ['pressure', '--force', '100']):
        argv = [*query, '--length', '0.23']
        assert main([*argv, '--config', CONFIG]) == 0
        single = capsys.readouterr().out
        assert main([*argv, '--config', multi, '--muscle', 'wrist_flexor']) == 0
        assert capsys.readouterr().out == single
    argv = ['force', '--pressure', '3e5', '--length', '0.23', '--config', multi]
    assert main([*argv, '--muscle', 'wrist_flexr']) == 2
    assert "no muscle 'wrist_flexr' (did you mean 'wrist_flexor'?)" in capsys.readouterr().err
