"""Ctrl-C during ``pma-model fit`` and ``bag estimate``: one line, exit code 130, no output file
(whole or nothing), and no process of the command left running.
"""

import contextlib
import os
from pathlib import Path
import selectors
import signal
import struct
import subprocess
import sys
import time

import pytest

from conftest import CONFIGS, REPO
from pma_model_ros.core.files import param_writer

MAP = REPO / 'pma_model_ros/core/data/dmsp_10_250_force_map.csv'
SPEC = REPO / 'config/muscles/dmsp_10_250.yaml'
DEADLINE = 120.0  #: [s] for the command to start, or to end once interrupted (a loaded machine)


#: ``python -m pma_model_ros.cli`` as a terminal starts a command in the foreground: SIGINT at
#: Python's handler, whatever this run inherited (a script's background job, ``colcon test &``
#: say, starts with SIGINT and SIGQUIT ignored, and a Python started so keeps them ignored).
FOREGROUND = (
    'import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); '
    "runpy.run_module('pma_model_ros.cli', run_name='__main__')"
)


def _start(argv: list[str], cwd: Path) -> subprocess.Popen:
    """``pma-model *argv`` in a session of its own (its workers in its process group), as in a
    terminal's foreground (:data:`FOREGROUND`), unbuffered.
    """
    return subprocess.Popen(
        [sys.executable, '-u', '-c', FOREGROUND, *argv],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _interrupted(proc: subprocess.Popen, group: bool = False) -> list[str]:
    """SIGINT to the command, or to its whole process group as Ctrl-C in a terminal sends it; its
    end awaited; its stderr lines but progress ones.
    """
    # how the command treats SIGINT when it is sent (blocked, ignored, caught: /proc's masks)
    masks = [ln for ln in Path(f'/proc/{proc.pid}/status').read_text().splitlines() if 'Sig' in ln]
    if group:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=DEADLINE)
    with pytest.raises(ProcessLookupError):  # nothing of its process group is left
        os.killpg(proc.pid, 0)
    lines = [line for line in err.splitlines() if not line.startswith('[')]
    assert lines, f'exit code {proc.returncode}, nothing on stderr but progress; {masks}\n{err}'
    return lines


@pytest.mark.parametrize('group', [False, True])
def test_ctrl_c_during_fit(tmp_path, group):
    """Interrupted once it has printed its first line (while fitting, in worker processes)."""
    out = tmp_path / 'fit.yaml'
    argv = ['fit', '--model', 'martens', '--data', str(MAP), '--muscle', str(SPEC)]
    proc = _start([*argv, '--out', str(out)], tmp_path)
    with selectors.DefaultSelector() as ready:
        ready.register(proc.stdout, selectors.EVENT_READ)
        assert ready.select(DEADLINE), 'fit printed nothing'
    first = proc.stdout.readline()
    assert first.startswith('geometry calibration'), first
    assert _interrupted(proc, group) == ['pma-model: interrupted']
    assert proc.returncode == 130
    assert list(tmp_path.iterdir()) == []


def _long_bag(folder: Path, seconds: int) -> Path:
    """A bag of ``seconds`` s of one muscle at 1 kHz: one simulated second, its messages
    repeated with their header stamps (CDR: 4 bytes of encapsulation, then stamp.sec as int32)
    and log times moved on by a second each time.
    """
    pytest.importorskip(
        'rosbags', reason='needs rosbags, a pip-only library: pip install -r requirements-dev.txt'
    )
    from pma_model_ros.bags.bag_io import BagWriter, messages, open_bag
    from pma_model_ros.bags.synthetic import record_simulation

    one = record_simulation(folder / 'one', 1.0, '/m1', rate=1000.0)
    with open_bag(one) as reader:
        recorded = list(messages(reader, reader.connections))
        with BagWriter(folder / 'run') as writer:
            topics = {c.id: writer.copy_topic(c) for c in reader.connections}
            for k in range(seconds):
                for connection, time_ns, data in recorded:
                    moved = bytearray(data)
                    sec = struct.unpack_from('<i', moved, 4)[0]
                    struct.pack_into('<i', moved, 4, sec + k)
                    writer.write_raw(topics[connection.id], time_ns + k * 10**9, bytes(moved))
    return folder / 'run'


def test_ctrl_c_during_bag_estimate(tmp_path):
    """Interrupted once its partial output bag is there: that partial bag is removed."""
    bag = _long_bag(tmp_path, 60)
    out = tmp_path / 'est'
    argv = ['bag', 'estimate', str(bag), '--config', str(CONFIGS['DMSP-10-250'])]
    proc = _start([*argv, '--out', str(out)], tmp_path)
    deadline = time.monotonic() + DEADLINE
    while not any(p.name.startswith('.est.') for p in tmp_path.iterdir()):
        with contextlib.suppress(subprocess.TimeoutExpired):  # a wait for its end, or 5 ms
            proc.wait(0.005)
        assert proc.returncode is None, proc.communicate()
        assert time.monotonic() < deadline, 'no partial bag appeared'
    assert _interrupted(proc) == ['pma-model: interrupted']
    assert proc.returncode == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ['one', 'run']


def test_a_parameter_file_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    """Interrupted between writing and renaming: the file given is as it was, nothing beside it."""
    path = tmp_path / 'fit.yaml'
    path.write_text('an older fit\n')

    def interrupt(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, 'replace', interrupt)
    with pytest.raises(KeyboardInterrupt):
        param_writer.write_parameters(path, {'node': {'ros__parameters': {'a': 1}}}, 'header')
    assert path.read_text() == 'an older fit\n'
    assert [p.name for p in tmp_path.iterdir()] == ['fit.yaml']
