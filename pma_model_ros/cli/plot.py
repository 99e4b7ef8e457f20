"""``pma-model plot``: the figures of :mod:`pma_model_ros.figures` (matplotlib imported when it
runs).
"""

from __future__ import annotations

import argparse
import functools
import math
from pathlib import Path

from .checks import add_overwrite_option, CliError, refuse_existing
from .identify import identify_shipped, table3
from ..core.files.param_file import load_muscle, read_parameters
from ..core.files.shipped_data import MAPPED_MUSCLES, shipped_force_map, shipped_spec
from ..core.identification.force_map import ForceMap, read_force_map_csv
from ..core.identification.progress import step
from ..core.physics.muscle_model import MuscleModel

#: Figures of ``pma-model plot`` and what each needs; ``all`` makes every one whose input is given.
PLOTS = {
    'force-map': '--config',
    'error-map': '--config',
    'models': None,
    'timeseries': '--bag',
    'joint': '--config',
    'drift': '--diagnostics',
}
#: The figures that draw measured points or errors against them: the map of ``--data``, else the
#: shipped map of a shipped muscle (:func:`measured_map`).
MAP_FIGURES = ('force-map', 'error-map')


def measured_map(config: str, muscle: MuscleModel, data: ForceMap | None) -> ForceMap:
    """The measured map the figures of the muscle file ``config`` draw: ``data`` (the user's
    ``--data``), else the shipped map of the muscle, only where the file's muscle is that one:
    the same name, geometry (D0, H0, Theta0) and identified lengths (``length_range``, as ``fit``
    and ``make-config`` write the map's).  CliError otherwise (one line asking for ``--data``):
    another muscle's dots are never drawn.
    """
    if data is not None:
        return data
    name = muscle.spec.name
    if name not in MAPPED_MUSCLES:
        raise CliError(
            f'{config}: no shipped force map for {name!r} (maps: {", ".join(MAPPED_MUSCLES)}); '
            'give the map it was fitted on: --data <csv>'
        )
    fmap, spec = shipped_force_map(name), shipped_spec(name)
    geometry = ('inner_diameter', 'membrane_thickness', 'fiber_angle')
    mine = {
        'length_range': (muscle.domain.length_min, muscle.domain.length_max),
        **{key: (getattr(muscle.spec, key),) for key in geometry},
    }
    theirs = {
        'length_range': (float(fmap.lengths.min()), float(fmap.lengths.max())),
        **{key: (getattr(spec, key),) for key in geometry},
    }
    differ = [
        f"{key} {_text(mine[key])}, the map's {_text(theirs[key])}"
        for key in mine
        if not all(math.isclose(a, b, rel_tol=1e-9) for a, b in zip(mine[key], theirs[key]))
    ]
    if differ:
        raise CliError(
            f'{config}: its {name} is not the shipped one of its map ({"; ".join(differ)}); '
            'give the map it was fitted on: --data <csv>'
        )
    return fmap


def _text(values: tuple[float, ...]) -> str:
    """One value, or a range in m."""
    text = ', '.join(f'{v:.6g}' for v in values)
    return f'[{text}] m' if len(values) > 1 else text


def cmd_plot(args: argparse.Namespace) -> None:
    try:
        from .. import figures
    except ImportError as err:
        raise CliError(
            f'plot needs matplotlib and rosbags (pip install matplotlib rosbags): {err}'
        ) from None
    wanted = list(PLOTS) if args.figure == 'all' else [args.figure]
    given = {'--config': args.config, '--bag': args.bag, '--diagnostics': args.diagnostics}
    for name in [n for n in wanted if PLOTS[n] and not given[PLOTS[n]]]:
        if args.figure != 'all':
            raise CliError(f'plot {name} needs {PLOTS[name]}')
        print(f'skipped {name}: no {PLOTS[name]}')
        wanted.remove(name)
    if args.data and not set(MAP_FIGURES) & set(wanted):
        raise CliError(
            f'--data is the measured map of {" and ".join(MAP_FIGURES)} (with --config); '
            f'plot {args.figure} draws none'
        )
    data = read_force_map_csv(args.data) if args.data else None
    jobs = {}  # file stem: a function drawing the figure (inputs read and checked first)
    for config in args.config or ():
        source = Path(config).stem
        if 'joints' in read_parameters(config):  # a joint file: its joint figures
            if 'joint' not in wanted:
                continue
            from ..core.files.joint_file import load_joints

            for joint in load_joints(config):
                jobs[f'joint_{source}_{joint.name}'] = functools.partial(
                    figures.joint_figure, joint
                )
            continue
        if args.figure == 'joint':
            raise CliError(f"plot joint needs a joint file (with 'joints:'), got {config}")
        model = load_muscle(config, args.model)
        if not set(MAP_FIGURES) & set(wanted):
            continue
        fmap = measured_map(config, model, data)
        for name, draw in (
            ('force-map', figures.force_map_figure),
            ('error-map', figures.error_map_figure),
        ):
            if name in wanted:
                stem = f'{name.replace("-", "_")}_{source}_{model.model.name}'
                jobs[stem] = functools.partial(draw, fmap, model)
    if 'timeseries' in wanted:
        name = Path(args.bag).stem
        series = figures.read_force_series(args.bag, args.namespace)
        jobs[f'timeseries_{name}'] = functools.partial(
            figures.timeseries_figure, *series, f'{name}: estimated vs measured force'
        )
    if 'drift' in wanted:
        name = Path(args.diagnostics).stem
        drift = figures.read_drift_series(args.diagnostics, args.joint)
        jobs[f'drift_{name}'] = functools.partial(
            figures.drift_figure, drift, f'{name}: drift monitor'
        )
    if 'models' in wanted:
        jobs['models'] = lambda: figures.models_figure(
            table3(identify_shipped(MAPPED_MUSCLES))['table3']
        )
    if not args.overwrite:
        refuse_existing(
            [args.out_dir / f'{stem}.{fmt}' for stem in jobs for fmt in args.format], 'plot'
        )
    written = []
    for k, (stem, draw) in enumerate(jobs.items(), 1):
        step(k, len(jobs), f'plotting {stem}')
        written += figures.save(draw(), args.out_dir, stem, args.format)
    for path in written:
        print(f'wrote {path}')


def add_plot_command(sub: argparse._SubParsersAction) -> None:
    """Add ``plot`` to the ``pma-model`` subparsers."""
    p = sub.add_parser(
        'plot',
        help='figures: force map, error map, model comparison, bag time series, joint, drift '
        'monitor',
    )
    p.add_argument('figure', choices=(*PLOTS, 'all'))
    p.add_argument(
        '--config',
        nargs='+',
        help='parameter file(s) of mapped muscles, for force-map and error-map; '
        'joint files, for joint',
    )
    p.add_argument(
        '--data',
        help='measured force map CSV (pressure_pa,length_m,force_n) that force-map and error-map '
        "draw the --config muscles against (default: a shipped muscle's own map)",
    )
    p.add_argument('--model', default=None, help="override the files' default model")
    p.add_argument(
        '--bag',
        help='bag with <ns>/force and <ns>/force_estimate (pma-model bag estimate), '
        'for timeseries',
    )
    p.add_argument(
        '--namespace', default=None, help="of the muscle's topics in --bag (default: the only one)"
    )
    p.add_argument(
        '--diagnostics',
        help='bag with /diagnostics of a model_node with residual.enabled, for drift',
    )
    p.add_argument(
        '--joint',
        default=None,
        help='the muscle of --diagnostics (its joint_name; default: the only one)',
    )
    p.add_argument(
        '--out-dir', type=Path, default=Path('.'), help='directory to write into (default: .)'
    )
    p.add_argument('--format', nargs='+', choices=('png', 'svg'), default=('png', 'svg'))
    add_overwrite_option(p, {'--out-dir': 'directory'})
    p.set_defaults(func=cmd_plot)
