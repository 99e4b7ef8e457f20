"""``pma-model plot``: the figures of :mod:`pma_model_ros.figures` (matplotlib imported when it
runs).
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

from .checks import add_overwrite_option, CliError, refuse_existing
from .identify import identify_shipped, table3
from ..core.files.param_file import load_muscle, read_parameters
from ..core.files.shipped_data import MAPPED_MUSCLES, shipped_force_map
from ..core.identification.progress import step

#: Figures of ``pma-model plot`` and what each needs; ``all`` makes every one whose input is given.
PLOTS = {
    'force-map': '--config',
    'error-map': '--config',
    'models': None,
    'timeseries': '--bag',
    'joint': '--config',
}


def cmd_plot(args: argparse.Namespace) -> None:
    try:
        from .. import figures
    except ImportError as err:
        raise CliError(
            f'plot needs matplotlib and rosbags (pip install matplotlib rosbags): {err}'
        ) from None
    wanted = list(PLOTS) if args.figure == 'all' else [args.figure]
    given = {'--config': args.config, '--bag': args.bag}
    for name in [n for n in wanted if PLOTS[n] and not given[PLOTS[n]]]:
        if args.figure != 'all':
            raise CliError(f'plot {name} needs {PLOTS[name]}')
        print(f'skipped {name}: no {PLOTS[name]}')
        wanted.remove(name)
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
        fmap = shipped_force_map(model.spec.name)
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
        'plot', help='figures: force map, error map, model comparison, bag time series, joint'
    )
    p.add_argument('figure', choices=(*PLOTS, 'all'))
    p.add_argument(
        '--config',
        nargs='+',
        help='parameter file(s) of mapped muscles, for force-map and error-map; '
        'joint files, for joint',
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
        '--out-dir', type=Path, default=Path('.'), help='directory to write into (default: .)'
    )
    p.add_argument('--format', nargs='+', choices=('png', 'svg'), default=('png', 'svg'))
    add_overwrite_option(p, {'--out-dir': 'directory'})
    p.set_defaults(func=cmd_plot)
