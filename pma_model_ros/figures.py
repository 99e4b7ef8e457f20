"""Figures of the identified muscles: matplotlib with the Agg canvas, no pyplot (no global state).

One function per figure, each returning a :class:`~matplotlib.figure.Figure`; :func:`save` writes
it. Axes read pressure in kPa (gauge), length in mm, force in N; errors are in % of the map's
largest measured force, the basis of Martens & Boblan eq. 23.  The physics comes from ``core``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter
import numpy as np

from .bags.bag_io import (
    BagError,
    connections_of,
    deserialize,
    DIAGNOSTIC_ARRAY,
    messages,
    open_bag,
    topic,
    WRENCH_STAMPED,
)
from .bags.estimate import muscle_namespace
from .core.identification.force_map import ForceMap
from .core.identification.protocols import max_error_percent
from .core.physics.flags import Flag
from .core.physics.joint import envelope, Joint
from .core.physics.muscle_model import MuscleModel
from .core.runtime.residual import Figures

FORMATS = ('png', 'svg')
DPI = 120  #: PNG resolution; the 8 in wide figures are 960 px, the width of the docs' figures
WIDTH = 8.0  #: figure width [in]
#: Local rc settings (applied with rc_context, never globally); the hash salt makes SVG ids
#: reproducible.
STYLE = {
    'font.size': 10,
    'axes.titlesize': 11,
    'legend.fontsize': 9,
    'axes.grid': True,
    'grid.alpha': 0.35,
    'svg.hashsalt': 'pma_model_ros',
}
SLACK_SHADE = '0.92'


def _figure(height: float) -> Figure:
    fig = Figure(figsize=(WIDTH, height), layout='constrained')
    FigureCanvasAgg(fig)
    return fig


def _kpa(pressure: np.ndarray) -> np.ndarray:
    return np.asarray(pressure) / 1e3


def _mm(length: np.ndarray) -> np.ndarray:
    return np.asarray(length) * 1e3


def _length_colors(n: int) -> list:
    return [matplotlib.colormaps['viridis'](x) for x in np.linspace(0.0, 0.85, n)]


@matplotlib.rc_context(STYLE)
def force_map_figure(fmap: ForceMap, model: MuscleModel) -> Figure:
    """Force over pressure, one curve per measured length, as in the paper's Figure 2.

    Measured points are dots (hollow where the muscle measured 0 N, slack); the model's served
    force (clipped at 0 N) is a solid line and its raw value where negative (slack) a dotted one,
    in the shaded band below 0 N.
    """
    fig = _figure(5.4)
    ax = fig.add_subplot()
    err = max_error_percent(
        fmap.force, model.force(fmap.pressure, fmap.length).force, fmap.max_force
    )
    pressure = np.linspace(0.0, fmap.pressure.max(), 400)
    for length, color in zip(fmap.lengths, _length_colors(fmap.lengths.size)):
        raw = model.force(pressure, length).raw
        slack = raw < 0
        ax.plot(
            _kpa(pressure[~slack]),
            raw[~slack],
            color=color,
            lw=2,
            label=f'{_mm(length):.0f} mm ({100 * (1 - length / model.spec.nominal_length):.1f} %)',
        )
        ax.plot(_kpa(pressure[slack]), raw[slack], color=color, lw=1.3, ls=':')
        at = fmap.length == length
        pulled = fmap.force[at] > 0
        ax.plot(_kpa(fmap.pressure[at][pulled]), fmap.force[at][pulled], 'o', ms=5, color=color)
        ax.plot(
            _kpa(fmap.pressure[at][~pulled]),
            fmap.force[at][~pulled],
            'o',
            ms=5,
            mfc='white',
            mec=color,
        )
    low = -0.12 * fmap.max_force
    ax.axhspan(low, 0.0, color=SLACK_SHADE, zorder=0)
    ax.text(
        0.01,
        low / 2,
        'slack: raw model < 0 N, served 0 N',
        va='center',
        fontsize=9,
        color='0.3',
        transform=ax.get_yaxis_transform(),
        bbox={'facecolor': SLACK_SHADE, 'edgecolor': 'none'},
    )
    if model.spec.max_pressure < pressure[-1]:
        ax.axvline(_kpa(model.spec.max_pressure), color='0.4', ls='--', lw=1)
        ax.text(
            _kpa(model.spec.max_pressure),
            0.98,
            'rated max pressure ',
            va='top',
            ha='right',
            fontsize=9,
            color='0.3',
            transform=ax.get_xaxis_transform(),
        )
    ax.set(
        xlim=(0, _kpa(pressure[-1]) * 1.01),
        ylim=(low, 1.05 * fmap.max_force),
        xlabel='gauge pressure p [kPa]',
        ylabel='tension F [N]',
        title=f'{model.spec.name}: measured force map and the {model.model.name} model '
        f'(err {err:.2f} %, eq. 23)',
    )
    lengths = ax.legend(title='length L (contraction)', loc='upper left')
    ax.add_artist(lengths)
    ax.legend(
        handles=[
            Line2D([], [], color='0.3', marker='o', ls='none', label='measured'),
            Line2D(
                [],
                [],
                color='0.3',
                marker='o',
                mfc='white',
                ls='none',
                label='measured 0 N (slack)',
            ),
            Line2D([], [], color='0.3', lw=2, label=f'{model.model.name}, served'),
            Line2D([], [], color='0.3', lw=1.3, ls=':', label=f'{model.model.name}, raw < 0'),
        ],
        loc='upper left',
        bbox_to_anchor=(0.0, 0.62),
    )
    return fig


def _grid(fmap: ForceMap, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(pressures, lengths, values on the pressure x length grid) of a full-grid map (every
    pressure measured at every length, once, as Tables A1 and A2); None for another map.
    """
    pressures, lengths = np.unique(fmap.pressure), np.unique(fmap.length)
    grid = np.full((pressures.size, lengths.size), np.nan)
    grid[np.searchsorted(pressures, fmap.pressure), np.searchsorted(lengths, fmap.length)] = values
    if np.isnan(grid).any() or grid.size != values.size:
        return None
    return pressures, lengths, grid


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges half way between grid points, the outer ones half a step out."""
    mid = (centres[1:] + centres[:-1]) / 2
    return np.r_[2 * centres[0] - mid[0], mid, 2 * centres[-1] - mid[-1]]


@matplotlib.rc_context(STYLE)
def error_map_figure(fmap: ForceMap, model: MuscleModel) -> Figure:
    """Model minus measured force at every measured point, in % of the largest measured force.

    One cell per point of a full-grid map, one coloured dot per point of another (a user's map,
    measured at pressures of its own per length).  Its largest magnitude is eq. 23's err.  Crosses
    mark measured 0 N (slack) points; the dashed line is where the model starts to pull (the
    inverse at 0 N).
    """
    fig = _figure(4.6)
    ax = fig.add_subplot()
    error = 100 * (model.force(fmap.pressure, fmap.length).force - fmap.force) / fmap.max_force
    limit = max(float(np.abs(error).max()), 1e-9)
    colours = {'cmap': 'RdBu_r', 'norm': TwoSlopeNorm(0.0, -limit, limit)}
    grid = _grid(fmap, error)
    if grid is not None:
        pressures, lengths, values = grid
        mesh = ax.pcolormesh(
            _kpa(_edges(pressures)),
            _mm(_edges(lengths)),
            values.T,
            edgecolors='white',
            linewidth=0.5,
            **colours,
        )
        xlim = _kpa(_edges(pressures)[[0, -1]])
    else:
        lengths = np.unique(fmap.length)
        mesh = ax.scatter(
            _kpa(fmap.pressure), _mm(fmap.length), c=error, s=90, edgecolors='0.4', **colours
        )
        xlim = (0.0, 1.03 * _kpa(fmap.pressure.max()))
    fig.colorbar(mesh, ax=ax, label=f'model − measured [% of max measured {fmap.max_force:.0f} N]')
    slack = fmap.force == 0
    ax.plot(
        _kpa(fmap.pressure[slack]),
        _mm(fmap.length[slack]),
        'x',
        color='0.25',
        ms=5,
        label='measured 0 N (slack)',
    )
    fine = np.linspace(lengths[0], lengths[-1], 200)
    onset = model.pressure(0.0, fine)
    reached = (onset.flags & Flag.SATURATED) == 0
    ax.plot(
        _kpa(onset.pressure[reached]),
        _mm(fine[reached]),
        '--',
        color='k',
        lw=1.5,
        label=f'{model.model.name} starts to pull',
    )
    worst = int(np.argmax(np.abs(error)))
    at = (_kpa(fmap.pressure[worst]), _mm(fmap.length[worst]))
    ax.plot(*at, 'o', ms=14, mfc='none', mec='white', mew=3.5)
    ax.plot(
        *at,
        'o',
        ms=14,
        mfc='none',
        mec='k',
        mew=1.5,
        label=f'max |error| {abs(error[worst]):.2f} % (eq. 23)',
    )
    ax.set(
        xlabel='gauge pressure p [kPa]',
        ylabel='length L [mm]',
        xlim=xlim,
        title=f'{model.spec.name}: {model.model.name} model error over the measured map',
    )
    ax.grid(False)
    fig.legend(loc='outside lower center', ncols=3)
    return fig


#: Bars of the model comparison: key in the table, label, colour.
_BARS = (
    ('paper', 'paper (Table 3)', '0.55'),
    ('paper_protocol', 'ours, paper protocol', 'tab:blue'),
    ('best', 'ours, best fit', 'tab:green'),
    ('cv', 'ours, worst held-out length (CV)', 'tab:orange'),
)


@matplotlib.rc_context(STYLE)
def models_figure(table: Mapping[str, Mapping]) -> Figure:
    """Eq. 23 err of every model: the paper's Table 3 beside ours, and our cross-validation.

    ``table`` is ``{muscle: {"default": name, model: {"paper", "paper_protocol", "best", "cv"}}}``,
    the ``pma-model reproduce --json`` object under ``"table3"``.
    """
    fig = _figure(3.0 * len(table) + 0.6)
    axes = fig.subplots(len(table), 1, sharex=True, squeeze=False)[:, 0]
    width = 0.8 / len(_BARS)
    for ax, (muscle, rows) in zip(axes, table.items()):
        names = [name for name in rows if name != 'default']
        x = np.arange(len(names))
        for i, (key, label, color) in enumerate(_BARS):
            values = [rows[name][key] for name in names]
            bars = ax.bar(
                x + (i - (len(_BARS) - 1) / 2) * width, values, width, color=color, label=label
            )
            ax.bar_label(
                bars,
                labels=[f'{v:.0f}' if v >= 100 else f'{v:.2f}' for v in values],
                fontsize=7.5,
                padding=2,
                rotation=90,
            )
        ax.set_yscale('log')
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f'{v:g}'))
        ax.set_ylim(0.1, 1e4)
        ax.set_ylabel('err, eq. 23 [%], log scale')
        ax.set_title(f'{muscle} (default model by CV: {rows["default"]})', loc='left')
        ax.grid(axis='x', visible=False)
    axes[-1].set_xticks(x, names)
    fig.legend(
        handles=axes[0].containers,
        labels=[label for _, label, _ in _BARS],
        loc='outside upper center',
        ncols=2,
    )
    return fig


def read_force_series(
    bag: str | Path, namespace: str | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time [s] since the first pair, measured [N], estimated [N]) at the header stamps both
    topics hold.

    Reads force.x of ``<ns>/force`` (measured) and ``<ns>/force_estimate`` (as ``pma-model bag
    estimate`` writes it), both WrenchStamped; of several estimates with one stamp the last (the
    newest pair) counts. ``namespace``: of the muscle's topics, default the only one in the bag.
    Raises BagError (one line).
    """
    with open_bag(bag) as reader:
        ns = muscle_namespace(reader, namespace)
        series: dict[str, dict[int, float]] = {
            topic(ns, 'force'): {},
            topic(ns, 'force_estimate'): {},
        }
        if not set(series) <= {c.topic for c in reader.connections}:
            raise BagError(
                f'{bag}: needs {" and ".join(series)}; add estimates with `pma-model bag estimate`'
            )
        connections = connections_of(reader, series, dict.fromkeys(series, WRENCH_STAMPED))
        for connection, _, data in messages(reader, connections):
            msg = deserialize(data, connection)
            series[connection.topic][msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = (
                msg.wrench.force.x
            )
    measured, estimated = series.values()
    stamps = np.array(sorted(measured.keys() & estimated.keys()), dtype=np.int64)
    if stamps.size < 2:
        raise BagError(f'{bag}: fewer than 2 stamps with both a measured force and an estimate')
    return (
        (stamps - stamps[0]) * 1e-9,
        np.array([measured[s] for s in stamps]),
        np.array([estimated[s] for s in stamps]),
    )


@matplotlib.rc_context(STYLE)
def timeseries_figure(
    time: np.ndarray, measured: np.ndarray, estimated: np.ndarray, title: str
) -> Figure:
    """Estimated and measured force [N] over time [s] at the same stamps, and their difference
    [N].
    """
    fig = _figure(5.0)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(2.2, 1))
    top.plot(time, measured, color='0.2', lw=1.6, label='measured')
    top.plot(time, estimated, color='tab:orange', lw=1.2, label='estimated')
    top.set(ylabel='tension F [N]', title=title)
    top.legend(loc='upper right')
    error = estimated - measured
    bottom.plot(time, error, color='tab:red', lw=1.0)
    bottom.axhline(0.0, color='0.3', lw=0.8)
    bottom.set_title(
        f'error: max |estimated − measured| {np.abs(error).max():.1f} N, '
        f'RMS {np.sqrt(np.mean(error**2)):.1f} N over {time.size} stamps',
        loc='left',
        fontsize=10,
    )
    bottom.set(xlabel='time t [s]', ylabel='estimated −\nmeasured [N]', xlim=(time[0], time[-1]))
    return fig


@dataclass(frozen=True)
class DriftSeries:
    """One muscle's drift monitor over a recording of /diagnostics: arrays over its reports."""

    name: str  #: the status name (``<namespace>/model_node: <joint>``)
    time: np.ndarray  #: [s] since the first report
    rms: np.ndarray  #: window RMS residual [% of max force] (NaN: too few samples)
    bias: np.ndarray  #: window bias [%]
    band: np.ndarray  #: the window's held-out band [%]
    level: np.ndarray  #: ``residual level``: 0 OK, 1 WARN, 2 ERROR
    reidentified: np.ndarray  #: ``reidentify served`` is ``re-identified`` (bool)


def read_drift_series(bag: str | Path, joint: str | None = None) -> DriftSeries:
    """The ``residual`` keys of model_node's statuses on ``/diagnostics`` in ``bag`` (a recording
    of a model_node with ``residual.enabled``), by header stamp; ``joint``: the muscle's (the end
    of its status name; default: the only status with residual keys). Raises BagError (one
    line).
    """
    rows: dict[str, list[tuple]] = {}
    with open_bag(bag) as reader:
        connections = connections_of(reader, ['/diagnostics'], {'/diagnostics': DIAGNOSTIC_ARRAY})
        for connection, _, data in messages(reader, connections):
            msg = deserialize(data, connection)
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            for status in msg.status:
                values = {kv.key: kv.value for kv in status.values}
                if 'residual level' not in values:  # not a monitored muscle of a model_node
                    continue
                f = Figures.parse(values['residual [% of max force]'])
                rows.setdefault(status.name, []).append(
                    (
                        stamp,
                        *((f.rms, f.bias, f.band) if f else (np.nan,) * 3),
                        ('OK', 'WARN', 'ERROR').index(values['residual level']),
                        values.get('reidentify served') == 're-identified',
                    )
                )
    names = sorted(rows) if joint is None else [n for n in rows if n.endswith(f': {joint}')]
    if len(names) != 1:
        found = ', '.join(n.rsplit(': ', 1)[-1] for n in sorted(rows)) or 'none'
        raise BagError(
            f'{bag}: /diagnostics needs one muscle of a model_node with residual.enabled'
            f'{f" named {joint}" if joint else ""} (muscles with residual keys: {found})'
            + ('; choose one with --joint' if len(rows) > 1 and joint is None else '')
        )
    stamp, rms, bias, band, level, reidentified = (np.array(c) for c in zip(*rows[names[0]]))
    return DriftSeries(
        names[0], (stamp - stamp[0]) * 1e-9, rms, bias, band, level, reidentified.astype(bool)
    )


@matplotlib.rc_context(STYLE)
def drift_figure(series: DriftSeries, title: str) -> Figure:
    """The window's RMS and bias residual [% of max force] against its held-out band over time
    [s], the WARN and ERROR reports shaded, and when a re-identified model was first served.
    """
    fig = _figure(3.6)
    ax = fig.subplots()
    t = series.time
    step = np.diff(t).min(initial=1.0) if t.size > 1 else 1.0
    for level, color, label in ((1, 'tab:orange', 'WARN'), (2, 'tab:red', 'ERROR')):
        at = np.flatnonzero(series.level == level)
        # each run of consecutive reports at the level: from half a report before to half after
        for k, run in enumerate(
            np.split(at, np.flatnonzero(np.diff(at) > 1) + 1) if at.size else ()
        ):
            ax.axvspan(
                t[run[0]] - step / 2,
                t[run[-1]] + step / 2,
                color=color,
                alpha=0.2,
                lw=0,
                label=None if k else f'{label} ({at.size} reports)',
            )
    ax.plot(t, series.band, color='0.2', lw=1.4, ls='--', label='held-out band')
    ax.plot(t, series.rms, color='tab:blue', lw=1.4, label='window RMS residual')
    ax.plot(t, series.bias, color='tab:green', lw=1.0, label='window bias')
    ax.axhline(0.0, color='0.3', lw=0.8)
    if series.reidentified.any():
        served = t[np.argmax(series.reidentified)]
        ax.axvline(
            served,
            color='tab:purple',
            lw=1.2,
            ls=':',
            label=f're-identified served ({served:.0f} s)',
        )
    ax.set(
        xlabel='time t [s]',
        ylabel='residual [% of max force]',
        title=f'{title}: {series.name}, {t.size} reports',
        xlim=(t[0], t[-1] + step * 0.5),
    )
    ax.legend(loc='best', fontsize=8)
    return fig


#: Co-contraction levels (the lower pressure [Pa gauge]) of the joint figure's envelope.
JOINT_LEVELS = (0.0, 200e3, 400e3, 600e3)


@matplotlib.rc_context(STYLE)
def joint_figure(joint: Joint) -> Figure:
    """Left: the reachable torque over the joint range, in all and at co-contraction levels (lower
    pressure). Right: the stiffness K [N·m/rad] at zero torque over angle and co-contraction level.
    """
    fig = _figure(3.8)
    left, right = fig.subplots(1, 2)
    angles = np.linspace(*joint.limits, 81)
    env = envelope(joint, angles, JOINT_LEVELS)
    left.fill_between(
        angles, env['torque_min'], env['torque_max'], color='0.9', label='any pressures'
    )
    for level, low, high, color in zip(
        JOINT_LEVELS, env['level_min'], env['level_max'], _length_colors(len(JOINT_LEVELS))
    ):
        left.plot(angles, high, color=color, lw=1.4, label=f'lower pressure {level / 1e3:.0f} kPa')
        left.plot(angles, low, color=color, lw=1.4, ls='--')
    left.axhline(0.0, color='0.3', lw=0.8)
    left.set(
        xlabel='joint angle θ [rad]',
        ylabel='torque τ [N·m]',
        title='reachable torque (max solid, min dashed)',
    )
    left.legend(loc='upper center', fontsize=7.5)
    p_max = min(m.spec.max_pressure for m in joint.muscles)
    levels = np.linspace(0.0, p_max, 81)
    grid = np.linspace(*joint.limits, 81)
    stiffness = np.array(
        [[joint.pressures_one(theta, 0.0, level).stiffness for theta in grid] for level in levels]
    )
    stiffness = np.ma.masked_where(stiffness <= 0, stiffness)  # both muscles slack
    right.set_facecolor(SLACK_SHADE)
    mesh = right.pcolormesh(grid, _kpa(levels), stiffness, shading='nearest', cmap='viridis')
    right.contour(
        grid,
        _kpa(levels),
        stiffness,
        levels=np.arange(2.0, stiffness.max(), 1.0),
        colors='white',
        linewidths=0.6,
    )
    right.text(
        0.5, 0.06, 'both muscles slack: K = 0', transform=right.transAxes, ha='center', fontsize=8
    )
    fig.colorbar(mesh, ax=right, label='stiffness K = −dτ/dθ [N·m/rad]')
    right.set(
        xlabel='joint angle θ [rad]',
        ylabel='co-contraction: lower pressure [kPa]',
        title='stiffness at zero torque',
    )
    right.grid(False)
    names = ' / '.join(
        f'{n} ({m.spec.name}, {m.model.name})' for n, m in zip(joint.muscle_names, joint.muscles)
    )
    fig.suptitle(
        f"joint '{joint.name}': {names}, r = {joint.transmission.radius(0.0) * 1e3:g} mm at 0 rad",
        fontsize=10,
    )
    return fig


def save(
    fig: Figure, out_dir: str | Path, stem: str, formats: Sequence[str] = FORMATS
) -> list[Path]:
    """Write ``out_dir/stem.<format>`` for each format (reproducible: no date, fixed SVG ids)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    with matplotlib.rc_context(STYLE):
        for fmt in formats:
            path = out_dir / f'{stem}.{fmt}'
            fig.savefig(path, dpi=DPI, metadata={'Date': None} if fmt == 'svg' else {})
            paths.append(path)
    return paths
