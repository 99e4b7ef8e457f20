"""``pma-model bag estimate|play`` and the options of ``pma-model fit --bag``; the bag tools
themselves are :mod:`pma_model_ros.bags`.

Only argparse here: rosbags (and rclpy, for ``bag play``) are imported when a command runs,
so the rest of ``pma-model`` works without them; without rosbags (from pip: its rosdep key is
``python3-rosbags-pip``) a bag command is one line and exit code 2 (:func:`_needs_rosbags`).
"""

from __future__ import annotations

import argparse
from contextlib import contextmanager
import os
from pathlib import Path
import shutil
import tempfile
from typing import Iterator

from .checks import add_overwrite_option, CliError
from ..core.files.node_parameters import PRESSURE_REFERENCES
from ..core.identification.force_map import ForceMap
from ..core.physics.geometry import MuscleSpec, STANDARD_ATMOSPHERE


def add_bag_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``bag estimate`` and ``bag play`` to the ``pma-model`` subparsers."""
    bag = sub.add_parser(
        'bag', help='rosbag2 recordings (mcap, sqlite3): offline estimation, replay'
    )
    commands = bag.add_subparsers(dest='bag_command', required=True)
    p = commands.add_parser(
        'estimate',
        help='what model_node would publish for a recording, into a new bag',
        description="Replays a recording's <ns>/pressure, <ns>/muscle_state (and "
        "<ns>/force_command) through model_node's logic and writes a new bag: "
        'the original messages plus <ns>/force_estimate, <ns>/pressure_command '
        'and /diagnostics (docs/bags.md). A parameter file with `muscles:` '
        "reads each muscle's topics under <ns>/<name>/, or the combined "
        'JointStates, as model_node does.',
    )
    p.add_argument('bag', help='input bag (directory, or .mcap / .db3 file)')
    p.add_argument(
        '--config', required=True, help='model_node parameter file, e.g. config/dmsp_10_250.yaml'
    )
    p.add_argument(
        '--out',
        required=True,
        help='output bag: a directory, or one storage file if it ends in .mcap or .db3',
    )
    p.add_argument('--csv', help='also write the estimates to this CSV file')
    add_overwrite_option(p, {'--out': 'bag', '--csv': 'file'})
    p.add_argument(
        '--outputs-only',
        action='store_true',
        help="write only what model_node publishes (no copy of the recording's other topics)",
    )
    p.add_argument(
        '--storage', choices=('mcap', 'sqlite3'), help="output storage (default: the input's)"
    )
    p.add_argument(
        '--namespace', help="namespace of the muscle's topics (default: the only one in the bag)"
    )
    p.add_argument('--model', help="override the file's default model")
    p.add_argument(
        '--joint',
        help="JointState entry of the muscle (default: the file's joint_name, else its muscle's "
        'name); a file with muscles: names them in its blocks',
    )
    p.add_argument(
        '--pressure-reference',
        choices=PRESSURE_REFERENCES,
        help="what the recorded fluid_pressure holds (default: the file's `pressure_reference`, "
        'else absolute)',
    )
    p.set_defaults(func=cmd_bag_estimate)
    p = commands.add_parser(
        'play',
        help="publish a recording's messages with their recorded timing (rclpy)",
        description='Like `ros2 bag play`: each message on its topic at its recorded log '
        'time (scaled by --rate), with the recorded QoS.',
    )
    p.add_argument('bag', help='input bag (directory, or .mcap / .db3 file)')
    p.add_argument('--rate', type=float, default=1.0, help='playback speed factor (default 1)')
    p.add_argument(
        '--clock',
        type=float,
        nargs='?',
        const=40.0,
        default=None,
        metavar='HZ',
        help='publish /clock (bag time) before every message and at HZ between them '
        '(default 40 Hz), for nodes with use_sim_time',
    )
    p.add_argument('--topics', nargs='+', metavar='TOPIC', help='play only these topics')
    p.add_argument(
        '--remap', nargs='+', default=[], metavar='FROM:=TO', help='publish topic FROM on TO'
    )
    p.add_argument(
        '--delay',
        type=float,
        default=0.0,
        help='wait this long [s] before the first message '
        '(with --clock: publishing the start time)',
    )
    p.add_argument(
        '--wait-for-subscribers',
        type=float,
        default=0.0,
        metavar='TIMEOUT',
        help='first wait up to TIMEOUT [s] until every played topic has a subscriber',
    )
    p.set_defaults(func=cmd_bag_play)


def _needs_rosbags() -> None:
    """Raise a ValueError (one line, exit code 2) when rosbags is not installed."""
    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise ValueError(
            'bag files need rosbags, a pip-only library: pip install rosbags==0.11.9'
        ) from None


def cmd_bag_estimate(args: argparse.Namespace) -> None:
    _needs_rosbags()
    from ..bags.estimate import estimate_bag
    from ..core.files.param_file import all_node_settings, node_pairing, read_parameters

    parameters = read_parameters(args.config)
    if args.pressure_reference:
        parameters['pressure_reference'] = args.pressure_reference
    if args.joint:
        if parameters.get('muscles'):
            raise CliError(
                f"--joint: {args.config} has muscles: {parameters['muscles']}; set each one's "
                'joint_name in its block'
            )
        parameters['joint_name'] = args.joint
    try:
        settings = all_node_settings(parameters, args.model)
    except ValueError as err:
        raise CliError(f'{args.config}: {err}') from None
    pairing = node_pairing(parameters)  # (checked by the engine)
    new_csv = args.csv is not None and not os.path.lexists(args.csv)
    with replacing(Path(args.out)) as out:
        summary = estimate_bag(
            args.bag,
            settings,
            out,
            names=parameters.get('muscles') or [],
            combined=parameters.get('input_mode') == 'combined',
            storage=args.storage,
            namespace=args.namespace,
            csv=args.csv,
            outputs_only=args.outputs_only,
            **pairing,
        )
        if not summary.estimates and any(summary.reasons.values()):
            if new_csv and os.path.lexists(args.csv):
                os.unlink(args.csv)
            raise CliError(
                f'{args.bag}: no force estimated, nothing written; rejected: '
                f'{_rejections(summary)}{_mismatch_hint(summary, args.config)}'
            )
    rejected = sum(n for key, n in summary.counts.items() if key.startswith('rejected'))
    print(
        f'{summary.namespace}: {summary.messages} messages read; wrote {summary.estimates} '
        f'force_estimate, '
        f'{summary.commands} pressure_command, {summary.diagnostics} /diagnostics ({rejected} '
        f'inputs rejected) '
        f'-> {args.out}' + (f' and {args.csv}' if args.csv else '')
    )
    if rejected:
        print(f'rejected: {_rejections(summary)}{_mismatch_hint(summary, args.config)}')
    for joint, line in summary.residual.items():
        print(f'{joint}: {line}')


def _rejections(summary) -> str:
    """The rejected inputs per muscle and reason: ``500 × invalid input: ...`` (of a reason
    whose texts differ, the first).
    """
    several = len(summary.reasons) > 1
    return '; '.join(
        f'{joint + ": " if several else ""}{n} × {text}'
        + (' (the first)' if n > 1 and not text.endswith(key) else '')
        for joint, reasons in summary.reasons.items()
        for key, (n, text) in reasons.items()
    )


def _mismatch_hint(summary, config: str) -> str:
    """What maps the recording to the file where most of its lengths were rejected for not
    matching it: the JointState names (--joint, joint_name), or the muscle's geometry (another
    muscle's file); '' where they were not.
    """
    lengths = summary.counts.get('received muscle_state', 0)
    named, outside = (
        sum(
            n
            for reasons in summary.reasons.values()
            for key, (n, _) in reasons.items()
            if pick(key)
        )
        for pick in (lambda key: key.startswith("joint '"), lambda key: key == 'length')
    )
    if named and 2 * named >= lengths:
        return (
            f"; the recording's JointState names (in brackets) hold no joint of {config} "
            f'{list(summary.reasons)}: name the recorded entry with --joint NAME (or joint_name '
            "in the file), or give the recorded muscle's file"
        )
    if outside and 2 * outside >= lengths:
        return (
            f'; the recorded lengths lie outside the geometry of the muscle of {config}: is it '
            "the recorded muscle's file?"
        )
    return ''


@contextmanager
def replacing(out: Path) -> Iterator[Path]:
    """Where to write a new bag that replaces ``out`` (``--overwrite``): a fresh path beside it,
    moved to ``out`` only when the writing succeeded; ``out`` itself if it does not exist.
    """
    if not (out.exists() or out.is_symlink()):
        try:
            yield out
        except BaseException:  # nothing written: no bag left behind
            if out.is_dir() and not out.is_symlink():
                shutil.rmtree(out)
            elif out.exists():
                out.unlink()
            raise
        return
    tmp = Path(tempfile.mkdtemp(prefix=f'.{out.name}.', suffix='.replacing', dir=out.parent))
    try:
        yield tmp / out.name
        if out.is_dir() and not out.is_symlink():
            shutil.rmtree(out)
        else:
            out.unlink()
        (tmp / out.name).rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def cmd_bag_play(args: argparse.Namespace) -> None:
    remaps = {}
    for rule in args.remap:
        source, sep, target = rule.partition(':=')
        if not (sep and source and target):
            raise ValueError(f'--remap {rule!r}: expected FROM:=TO')
        remaps[source] = target
    if not (
        args.rate > 0
        and args.delay >= 0
        and args.wait_for_subscribers >= 0
        and (args.clock is None or args.clock > 0)
    ):
        raise ValueError('--rate and --clock must be > 0, --delay and --wait-for-subscribers >= 0')
    _needs_rosbags()
    from ..bags.play import play

    count = play(
        args.bag,
        rate=args.rate,
        clock=args.clock,
        topics=args.topics,
        remaps=remaps,
        delay=args.delay,
        wait_for_subscribers=args.wait_for_subscribers,
    )
    print(f'published {count} messages')


def add_fit_bag_options(p: argparse.ArgumentParser) -> None:
    """The options of ``fit --bag`` (the calibration from a recording)."""
    g = p.add_argument_group('with --bag (quasi-static samples of a recording; docs/bags.md)')
    g.add_argument(
        '--namespace', help="namespace of the muscle's topics (default: the only one in the bag)"
    )
    g.add_argument(
        '--force-topic',
        help='measured force: WrenchStamped (force.x) or JointState (effort); '
        'default <ns>/force if recorded, else the effort in <ns>/muscle_state',
    )
    g.add_argument('--joint', help="JointState entry of the muscle (default: the spec's name)")
    g.add_argument(
        '--ambient-pressure',
        type=float,
        default=STANDARD_ATMOSPHERE,
        help=f'[Pa absolute] (default {STANDARD_ATMOSPHERE:g})',
    )
    g.add_argument(
        '--pressure-reference',
        choices=PRESSURE_REFERENCES,
        default='absolute',
        help="what the recorded fluid_pressure holds (default absolute, the message's definition)",
    )
    g.add_argument('--window', type=float, default=1.0, help='quasi-static window [s] (default 1)')
    g.add_argument(
        '--max-length-rate',
        type=float,
        default=1e-3,
        help='quasi-static |dL/dt| bound [m/s] (default 0.001)',
    )
    g.add_argument(
        '--max-pressure-rate',
        type=float,
        default=50e3,
        help='quasi-static |dp/dt| bound [Pa/s] (default 50000)',
    )


def bag_force_map(
    args: argparse.Namespace, spec: MuscleSpec, two_branches: bool = False
) -> ForceMap:
    """The force map of ``fit --bag``: the recording's quasi-static samples, averaged per cell (per
    hysteresis branch with ``two_branches``).
    """
    _needs_rosbags()
    from ..bags.calibrate import force_map_from_bag, QuasiStatic

    criterion = QuasiStatic(args.window, args.max_length_rate, args.max_pressure_rate)
    # reading - ambient = gauge
    ambient = 0.0 if args.pressure_reference == 'gauge' else args.ambient_pressure
    calibration = force_map_from_bag(
        args.bag,
        args.joint or spec.name,
        ambient,
        criterion,
        args.namespace,
        args.force_topic,
        two_branches,
    )
    print(
        f'{args.bag}: {calibration.kept} of {calibration.samples} samples quasi-static '
        f'(|dL/dt| <= {criterion.max_length_rate:g} m/s, |dp/dt| <= '
        f'{criterion.max_pressure_rate:g} Pa/s over {criterion.window:g} s), '
        f'{calibration.force_map.force.size} cells'
    )
    return calibration.force_map
