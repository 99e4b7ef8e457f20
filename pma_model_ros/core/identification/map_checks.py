"""Whether a force map and a muscle spec belong together, judged by the braid's physics before
any fit: the spec's geometry against the lengths the map pulls at, absolute pressures, single rows
above the braid's pull (outliers), the whole map above or below it (another force unit, or
another muscle's spec).

The ideal braid (Chou and Hannaford; Martens & Boblan 2017, eqs. 1-4) pulls F = -p dV/dL = p pi
D^2/4 (3 cos^2 Theta - 1) / sin^2 Theta at the diameter D and braid angle Theta of length L (cos
Theta = L / L_Fiber); scaled to the outer diameter D0 + 2 H0 it bounds what a real muscle pulls:
the four measured maps this package was judged on reach 0.83..1.03 of it, at their longest
length.
"""

from __future__ import annotations

import math

import numpy as np

from .force_map import ForceMap
from ..hints import length_hint
from ..physics import geometry as geo
from ..physics.geometry import MuscleSpec, STANDARD_ATMOSPHERE

#: Largest ratio of a measured force to the outer braid's pull at its pressure and length
#: (:func:`~pma_model_ros.core.physics.geometry.braid_pull`; the measured maps: at most 1.03, so
#: half as much again is no map's).
BRAID_LIMIT = 1.5
#: Smallest ratio the map's largest one may take, judged on a map with a row within
#: :data:`_NEAR_REST` of L0: the measured maps in newtons reach 0.83..1.03 at their rest-length
#: rows and at least 0.41 at rows up to 9 % contracted; lbf give at most 1.03 / 4.45 = 0.23.
BRAID_LEAST = 0.3
#: [-] A map whose longest row is at least this fraction of L0 is judged against BRAID_LEAST.
_NEAR_REST = 0.91
#: [-] A ratio the map's largest reaches in newtons, to name the unit a scaled map was written in.
_TYPICAL = 0.9
#: (unit, its symbol, newtons per unit) a whole map's forces may have been written in.
FORCE_UNITS = (
    ('lbf', 'lbf', 4.4482216152605),
    ('kgf', 'kgf', 9.80665),
    ('kN', 'kN', 1e3),
    ('N·mm or mN', 'mN', 1e-3),
)
#: At most this share of the pulling points (and at least 2 points) above the braid's pull are
#: outlying rows; more say the whole map, or the spec, is off.
_FEW = 0.1
#: Pressures [Pa] between these fractions of the standard atmosphere, with no force measured at the
#: lowest of them, are absolute: ambient from 4000 m altitude (0.6) to the highest weather (1.08),
#: plus a first step of a map (Table A2's 5 kPa: 1.13), rounded out.
_AMBIENT_BAND = (0.5, 1.2)
#: [fraction of the standard atmosphere] A muscle at its rest length pulls from a threshold of tens
#: of kPa gauge (:func:`rest_threshold` of Tables A1/A2: 38 / 31 kPa; of the independent DMSP-20
#: and DMSP-10: 60 and -9 kPa, sensor zeros of about +10 kPa in them); this or more is the
#: atmosphere (ambient up to 1000 m altitude; higher, if the muscle's own threshold adds to it).
_REST_THRESHOLD = 0.9
#: [-] The longest row is the rest-length row if at least this fraction of L0 (Table A1: 0.987).
_AT_REST = 0.985
#: [fraction of the max force] Pulling points: above the force sensor's zero.
_PULLING = 0.03
#: [fraction of the top pressure] Points judged against the braid's pull: working pressures.
_WORKING = 0.25


def check_against_spec(fmap: ForceMap, spec: MuscleSpec) -> None:
    """Refuse (ValueError) a map that ``spec``'s braid cannot have measured, naming what is off,
    the geometry first: lengths beyond the braid's fibre length, the map pulling below its full
    contraction (the spec is the suspect), a few rows above the braid's pull (by their file
    lines), absolute pressures, the whole map above or below the braid's pull (another force
    unit, or another muscle's spec).
    """
    _check_fibre(fmap, spec)
    _check_contraction(fmap, spec)
    ratio = _pull_ratio(fmap, spec)
    _check_outliers(fmap, spec, ratio)
    _check_absolute(fmap, spec)
    _check_scale(fmap, spec, ratio)


def _check_fibre(fmap: ForceMap, spec: MuscleSpec) -> None:
    """Lengths at or beyond the fibre length L0/cos(Theta0), which no braid of the spec reaches:
    lengths in cm or mm, or another muscle's map.
    """
    longest, fibre = float(fmap.length.max()), float(geo.fiber_length(spec))
    if longest < fibre:
        return
    if longest > 1:
        raise ValueError(
            f'length_m reaches {longest:g} m, beyond what the geometry of {spec.name} can take '
            f'(0 < L < {fibre:.6g} m, its fibre length L0/cos(Theta0)); '
            + length_hint(longest, spec.nominal_length)
        )
    raise ValueError(
        f'the map and the spec {spec.name} do not belong together: length_m reaches {longest:g} '
        f'm, {_beyond(fmap, spec)}, beyond the {fibre:.6g} m a braid of the spec reaches (its '
        f'fibre length L0/cos(Theta0)){_stronger(fmap, spec)}; {_GIVE}'
    )


def _check_contraction(fmap: ForceMap, spec: MuscleSpec) -> None:
    """The map pulls at lengths the spec's braid reaches only beyond its full contraction."""
    shortest = geo.shortest_length(spec)
    taut = fmap.force > _PULLING * fmap.max_force
    if np.any(taut & (fmap.length <= shortest)):
        length = float(fmap.length[taut].min())
        force = fmap.force[taut & (fmap.length == length)].max()
        raise ValueError(
            f'the map pulls {force:g} N at {length:g} m, but the braid of the spec {spec.name} is '
            f'fully contracted at {shortest:.4g} m (L0/cos(Theta0)/sqrt(3), Theta0 '
            f'{math.degrees(spec.fiber_angle):.1f} deg, L0 {spec.nominal_length:g} m) and pulls '
            'nothing shorter: the spec is the suspect; check its fiber_angle (rad; Festo DMSP: '
            '0.4992 = 28.6 deg) and nominal_length'
        )


def rest_threshold(fmap: ForceMap, length: float) -> float | None:
    """[Pa] The pressure from which the map pulls at ``length``: the highest pressure of no
    force below the first pulling point, or the zero of the line through the three lowest pulling
    points, whichever is higher; None without two pulling points.
    """
    at = fmap.length == length
    pressure, force = fmap.pressure[at], fmap.force[at]
    pulling = force > _PULLING * fmap.max_force
    if np.unique(pressure[pulling]).size < 2:
        return None
    order = np.argsort(pressure[pulling])[:3]
    slope, intercept = np.polyfit(pressure[pulling][order], force[pulling][order], 1)
    below = pressure[(force <= 0) & (pressure < pressure[pulling].min())]
    line = -intercept / slope if slope > 0 else -math.inf
    return float(max(line, below.max() if below.size else -math.inf))


def _check_absolute(fmap: ForceMap, spec: MuscleSpec) -> None:
    """Absolute pressures: the map pulls at its rest-length row only from about one atmosphere
    on; where it has no such row to judge by, it starts at ambient with no force.  A map whose
    rest-length row pulls from tens of kPa is gauge, wherever it starts (a sensor's zero).
    """
    longest = float(fmap.length.max())
    at_rest = longest >= _AT_REST * spec.nominal_length
    threshold = rest_threshold(fmap, longest) if at_rest else None
    if threshold is not None and threshold < _REST_THRESHOLD * STANDARD_ATMOSPHERE:
        return
    lowest = float(fmap.pressure.min())
    low, high = (f * STANDARD_ATMOSPHERE for f in _AMBIENT_BAND)
    gauge = 'the map takes gauge pressure = absolute - ambient'
    if low <= lowest <= high and not np.any(fmap.force[fmap.pressure == lowest]):
        raise ValueError(
            f'pressure_pa starts at {lowest:g} Pa with no force at any length: about ambient '
            f'({STANDARD_ATMOSPHERE:g} Pa), so absolute pressures; {gauge} '
            f'(e.g. {lowest - STANDARD_ATMOSPHERE:g} Pa)'
        )
    if threshold is not None:
        raise ValueError(
            f'pressure_pa: at its longest length {longest:g} m (L0 {spec.nominal_length:g} m) '
            f'the map pulls only from about {threshold / 1e3:.0f} kPa on, where a muscle at its '
            'rest length pulls from tens of kPa gauge (Tables A1/A2: 38 / 31 kPa): pressures '
            f'with the atmosphere in them, absolute ones; {gauge} (at sea level '
            f'{STANDARD_ATMOSPHERE:g} Pa)'
        )


def _pull_ratio(fmap: ForceMap, spec: MuscleSpec) -> np.ndarray:
    """Each point's force over the braid's pull at its pressure and length
    (:func:`~pma_model_ros.core.physics.geometry.braid_pull`); 0 where the braid pulls nothing,
    the point pulls less than :data:`_PULLING` of the map's max force, or its pressure is below
    :data:`_WORKING` of the map's top: there a force sensor's zero, the sleeve's stretch beyond L0
    or a pressure sensor's zero outweigh the braid's pull.
    """
    area = geo.braid_pull(spec, fmap.length)
    use = (
        (fmap.force > _PULLING * fmap.max_force)
        & (fmap.pressure >= _WORKING * fmap.pressure.max())
        & (area > 0)
    )
    ratio = np.zeros(fmap.force.size)
    ratio[use] = fmap.force[use] / (fmap.pressure[use] * area[use])
    return ratio


def _braid(spec: MuscleSpec) -> str:
    return (
        f'the ideal braid of {spec.name} (D0 {spec.inner_diameter * 1e3:g} mm + 2 H0, Theta0 '
        f'{math.degrees(spec.fiber_angle):.1f} deg, L0 {spec.nominal_length:g} m)'
    )


def _pulls(fmap: ForceMap, spec: MuscleSpec, ratio: np.ndarray, i: int) -> str:
    """What point ``i`` measured against what the braid pulls there."""
    return (
        f'{fmap.force[i]:g} at {fmap.pressure[i]:g} Pa, {fmap.length[i]:g} m: {ratio[i]:.4g} x '
        f'the {fmap.force[i] / ratio[i]:.4g} N {_braid(spec)} pulls there'
    )


def _check_outliers(fmap: ForceMap, spec: MuscleSpec, ratio: np.ndarray) -> None:
    """A few rows above the braid's pull, the rest of the map within it: named by file line."""
    above = np.flatnonzero(ratio > BRAID_LIMIT)
    if not 0 < above.size <= max(2, _FEW * np.count_nonzero(ratio)):
        return
    rows = '; '.join(
        f'{_where(fmap, i)}: {_pulls(fmap, spec, ratio, i)}'
        for i in above[np.argsort(-ratio[above])][:3]
    )
    raise ValueError(
        f'{above.size} row(s) of force_n far above the rest of the map: {rows}; the other rows '
        f'stay within {BRAID_LIMIT:g} x it: a typing error? correct or delete the row'
    )


def _check_scale(fmap: ForceMap, spec: MuscleSpec, ratio: np.ndarray) -> None:
    """The whole map above or below the braid's pull: another force unit (named, with its factor)
    if one brings the map within it, else another muscle's spec.
    """
    top = int(np.argmax(ratio))
    scale = float(ratio[top])
    near_rest = fmap.length.max() >= _NEAR_REST * spec.nominal_length
    if scale == 0 or scale <= BRAID_LIMIT and (scale >= BRAID_LEAST or not near_rest):
        return
    unit, symbol, per = min(FORCE_UNITS, key=lambda u: abs(math.log(scale * u[2] / _TYPICAL)))
    if BRAID_LEAST <= scale * per <= BRAID_LIMIT:
        raise ValueError(
            f'force_n reaches {_pulls(fmap, spec, ratio, top)}, the whole map alike: force in '
            f'newtons; {unit}? {fmap.force[top]:g} {symbol} = {fmap.force[top] * per:.6g} N (the '
            f'map x {per:g})'
        )
    beyond = fmap.length.max() / spec.nominal_length - 1
    raise ValueError(
        f'the map and the spec {spec.name} do not belong together: force_n reaches '
        f'{_pulls(fmap, spec, ratio, top)}'
        + (f', and its lengths reach {_beyond(fmap, spec)}' if beyond > 0.01 else '')
        + f'; {_GIVE}'
    )


#: What to do about a map and a spec of different muscles.
_GIVE = 'give the spec of the muscle measured (its L0, D0, H0 and Theta0)'


def _beyond(fmap: ForceMap, spec: MuscleSpec) -> str:
    """How far the map's longest length lies beyond the spec's L0."""
    beyond = 100 * (fmap.length.max() / spec.nominal_length - 1)
    return f'{beyond:.1f} % beyond its L0 {spec.nominal_length:g} m'


def _stronger(fmap: ForceMap, spec: MuscleSpec) -> str:
    """``, and its forces x times ...``: the map's largest force over what the spec's braid
    pulls at its pressure at L0, where more than the braid's limit.
    """
    top = int(np.argmax(fmap.force / np.maximum(fmap.pressure, 1.0)))
    pull = fmap.pressure[top] * geo.braid_pull(spec, spec.nominal_length)
    if fmap.force[top] <= BRAID_LIMIT * pull:
        return ''
    return (
        f', and its forces reach {fmap.force[top] / pull:.3g} x what {_braid(spec)} pulls at L0 '
        f'({fmap.force[top]:g} N at {fmap.pressure[top]:g} Pa against {pull:.4g} N)'
    )


def _where(fmap: ForceMap, index: int) -> str:
    """``line N`` of the map's file, or ``point N`` of a map without lines."""
    if fmap.line is not None:
        return f'line {int(fmap.line[index])}'
    return f'point {index + 1}'


def unsolvable(spec: MuscleSpec, err: Exception) -> str:
    """The line for a fit whose linear algebra failed (``numpy.linalg.LinAlgError``) on a map that
    passed :func:`check_against_spec`: a map and a spec that do not belong together, as a rule.
    """
    return (
        f"the fit's least squares found no solution ({err}): the map and the spec {spec.name} "
        f'most likely do not belong together; {_GIVE}'
    )
