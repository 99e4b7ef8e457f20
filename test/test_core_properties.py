"""Property-based tests (hypothesis) of the core, over every model of every shipped parameter file.

Each generated example checks a small array of points in one vectorised call; the examples are
derandomised (the same on every run). Under CI=true (test/budget.py), 13,000 examples, 10,000 of
them on the force and its inverse:

- served force >= 0 after clipping, and the flags that say why (2,500);
- force non-decreasing in pressure at a fixed length exactly where dF/dp = 2 q2 p + q1 >= 0 on
  [0, max_pressure] (2,000), and which shipped models are not monotonic in their validity domain;
- inverse round trips pressure -> force -> pressure -> force and force -> pressure -> force (2 x
  1,500);
- any float input (NaN, inf, negative, huge) to MuscleModel.force/.pressure: no exception, no
  warning, NaN exactly where INVALID_INPUT (2,500);
- bad parameters: ValueError and nothing else from Model.check_params, MuscleSpec, Domain and
  param_file.muscle_model (4 x 750).

Where the shipped models are not monotonic in pressure (identified parameters; q1 < 0 or q1 + 2 q2
p_max < 0): in the validity domain only ``andrikopoulos``, at its shortest lengths (DMSP-10-250: L
< 0.213 m, DMSP-20-300: L < 0.234 m), where q1 < 0 makes the raw force negative for every p > 0
(served: 0 N, CLIPPED). Below the validity domain every model falls with pressure at short enough
lengths (e.g. ``mckibben`` below L_F / sqrt(3), 0.164 m on the DMSP-10-250; ``wickramatunge`` below
min L, where its q2 = c3 (L - min L) < 0); above L0, ``sarosi`` on the DMSP-10-250 (L > 0.271 m)
and ``sarosi_hysteresis`` (L > 0.107 m) do too. Outside the domain MuscleModel evaluates the model
at the nearest domain length, so the served force there follows the domain's edge; the monotonicity
test samples lengths in [L0 / 1000, L0] and checks the slope at that operating length.
"""

import copy
import math
import warnings

from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import array_shapes, arrays
import numpy as np
import pytest

from budget import examples
from conftest import CONFIGS
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.geometry import MuscleSpec
from pma_model_ros.core.physics.models import Domain, MODELS
from pma_model_ros.core.physics.muscle_model import MuscleModel, VENTED_BAND

PARAMETERS = {muscle: read_parameters(path) for muscle, path in CONFIGS.items()}
MUSCLES = [
    muscle_model(parameters, name)
    for parameters in PARAMETERS.values()
    for name in parameters['models']
]
RATES = (-0.01, 0.0, 0.01)  # length rate [m/s]: shortening, unknown, lengthening


def coefficients(muscle: MuscleModel, length: np.ndarray, rate: float) -> tuple[np.ndarray, ...]:
    q = muscle.model.coefficients(muscle.theta, muscle.spec, muscle.domain, length, np.sign(rate))
    return np.broadcast_arrays(*q)


def flagged(flags: np.ndarray, flag: Flag) -> np.ndarray:
    return (flags & flag) != 0


def working_length(muscle: MuscleModel, unit: np.ndarray) -> np.ndarray:
    """Lengths in [L0 / 1000, L0] [m] from unit floats in [0, 1]: the slack region, the validity
    domain, up to L0.
    """
    return (1e-3 + unit * (1 - 1e-3)) * muscle.spec.nominal_length


def domain_length(muscle: MuscleModel, unit: np.ndarray) -> np.ndarray:
    """Lengths served [m] (the identified range, or the envelope where the model extrapolates) from
    unit floats.
    """
    low, high = muscle.limits.length_low, muscle.limits.length_high
    return low + unit * (high - low)


def operating_length(muscle: MuscleModel, length: np.ndarray) -> np.ndarray:
    """Where MuscleModel evaluates the model: the length held inside the lengths served [m]."""
    return np.clip(length, muscle.limits.length_low, muscle.limits.length_high)


def units(size: int = 8):
    """Arrays of 1 to ``size`` floats in [0, 1]."""
    return arrays(np.float64, st.integers(1, size), elements=st.floats(0, 1))


# --- served force >= 0 after clipping
# ---------------------------------------------------------------


@examples(2500)
@given(st.sampled_from(MUSCLES), units(), units(), st.sampled_from(RATES))
def test_served_force_is_nonnegative_clipped_raw_force(muscle, u_p, u_L, rate):
    n = min(u_p.size, u_L.size)
    p = (3 * u_p[:n] - 1) * muscle.spec.max_pressure  # p in [-p_max, 2 p_max]
    L = working_length(muscle, u_L[:n])
    result = muscle.force(p, L, rate)
    assert not np.any(flagged(result.flags, Flag.INVALID_INPUT))
    assert np.all(result.force >= 0)
    np.testing.assert_array_equal(result.force, np.maximum(result.raw, 0.0))
    np.testing.assert_array_equal(flagged(result.flags, Flag.CLIPPED), result.raw < 0)
    np.testing.assert_array_equal(
        flagged(result.flags, Flag.PRESSURE_OUT_OF_RANGE),
        (p < -VENTED_BAND) | (p > muscle.limits.pressure_top),
    )
    np.testing.assert_array_equal(flagged(result.flags, Flag.BELOW_AMBIENT), p < -VENTED_BAND)
    served = np.clip(p, 0, muscle.limits.pressure_top)
    np.testing.assert_array_equal(
        flagged(result.flags, Flag.EXTRAPOLATED),
        (served > muscle.limits.pressure_known)
        | (operating_length(muscle, L) < muscle.domain.length_min)
        | (operating_length(muscle, L) > muscle.domain.length_max),
    )


# --- monotonic in pressure exactly where dF/dp >= 0
# ---------------------------------------------------


@examples(2000)
@given(st.sampled_from(MUSCLES), units(), units(size=24), st.sampled_from(RATES))
def test_force_rises_with_pressure_exactly_where_the_slope_is_nonnegative(muscle, u_L, u_p, rate):
    """dF/dp = 2 q2 p + q1 is linear in p, so its values at 0 and max_pressure decide
    monotonicity.
    """
    p_max = muscle.spec.max_pressure
    L = working_length(muscle, u_L)
    p = np.sort(np.r_[0.0, u_p, 1.0]) * p_max
    q2, q1, q0 = coefficients(muscle, operating_length(muscle, L), rate)
    rising = np.minimum(q1, q1 + 2 * q2 * p_max) >= 0
    result = muscle.force(p[None, :], L[:, None], rate)
    # bound of |F_raw| on [0, p_max]
    scale = np.abs(q0) + np.abs(q1) * p_max + np.abs(q2) * p_max**2
    tol = 1e-12 * scale[:, None]
    assert np.all(np.diff(result.raw, axis=1)[rising] >= -tol[rising])
    assert np.all(np.diff(result.force, axis=1)[rising] >= -tol[rising])
    # Elsewhere the raw force falls: from the lower to the higher end of an interval where dF/dp <
    # 0.
    with np.errstate(divide='ignore', invalid='ignore'):
        turn = np.clip(-q1 / (2 * q2), 0, p_max)  # the vertex, where q2 != 0
    falls_at_zero = q1 < 0
    p_lo = np.where(falls_at_zero, 0.0, turn)
    p_hi = np.where(falls_at_zero, np.where(q2 > 0, turn, p_max), p_max)
    expected_drop = (q2 * p_lo + q1) * p_lo - (q2 * p_hi + q1) * p_hi
    falls = ~rising & (expected_drop > 1e-9 * scale)
    drop = muscle.force(p_lo, L, rate).raw - muscle.force(p_hi, L, rate).raw
    assert np.all(drop[falls] > 0)


@pytest.mark.parametrize('muscle', MUSCLES, ids=[f'{m.spec.name}-{m.model.name}' for m in MUSCLES])
def test_which_models_are_monotonic_in_their_validity_domain(muscle):
    """Documented above: on the shipped parameters only andrikopoulos falls with pressure in its
    domain, and hildebrandt of DMSP-10-250 extrapolated below 0.179 m (its shortest measured
    length is 0.198 m); both only where they serve 0 N at every pressure.
    """
    L = domain_length(muscle, np.linspace(0, 1, 2001))
    falling = np.zeros(L.shape, bool)
    for rate in RATES:
        q2, q1, _ = coefficients(muscle, L, rate)
        falling |= np.minimum(q1, q1 + 2 * q2 * muscle.spec.max_pressure) < 0
    assert falling.any() == (
        muscle.model.name == 'andrikopoulos'
        or (muscle.model.name, muscle.spec.name) == ('hildebrandt', 'DMSP-10-250')
    )
    if falling.any():
        # At the shortest lengths only, where the raw force is <= 0 for every p > 0: served 0 N
        # there.
        np.testing.assert_array_equal(falling, L <= L[falling].max())
        assert np.all(muscle.force(muscle.spec.max_pressure, L[falling]).force == 0)


# --- inverse round trips
# ----------------------------------------------------------------------------


@examples(1500)
@given(st.sampled_from(MUSCLES), units(), units(), st.sampled_from(RATES))
def test_round_trip_pressure_force_pressure_force(muscle, u_p, u_L, rate):
    """Where the muscle pulls and pulls harder with pressure: force(pressure(force(p))) = force(p),
    1e-9.
    """
    n = min(u_p.size, u_L.size)
    p, L = u_p[:n] * muscle.spec.max_pressure, domain_length(muscle, u_L[:n])
    forward = muscle.force(p, L, rate)
    q2, q1, _ = coefficients(muscle, L, rate)
    valid = (forward.raw > 1e-3) & (q1 + 2 * q2 * p > 0)
    back = muscle.pressure(forward.force, L, rate)
    assert not np.any(flagged(back.flags, Flag.SATURATED | Flag.INVALID_INPUT)[valid])
    again = muscle.force(back.pressure, L, rate)
    np.testing.assert_allclose(again.force[valid], forward.force[valid], rtol=1e-9, atol=0)


@examples(1500)
@given(st.sampled_from(MUSCLES), units(), units(), st.sampled_from(RATES))
def test_round_trip_force_pressure_force(muscle, u_F, u_L, rate):
    """Any force between the pull-start force and the force at max_pressure comes back,
    unsaturated.
    """
    n = min(u_F.size, u_L.size)
    L = domain_length(muscle, u_L[:n])
    low = muscle.force(0.0, L, rate).force
    high = muscle.force(muscle.spec.max_pressure, L, rate).force
    F = low + u_F[:n] * (high - low)
    back = muscle.pressure(F, L, rate)
    reachable = high > low
    assert not np.any(
        flagged(back.flags, Flag.SATURATED | Flag.INVALID_INPUT)[reachable & (F > 0)]
    )
    again = muscle.force(back.pressure, L, rate).force
    np.testing.assert_allclose(again[reachable], F[reachable], rtol=1e-9, atol=1e-9 * high.max())


# --- any input: no exception, NaN exactly with INVALID_INPUT
# -------------------------------------------

ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True)
#: Values: a scalar or an array (n,) of any float.
ANY_VALUE = ANY_FLOAT | arrays(
    np.float64, array_shapes(max_dims=1, max_side=6), elements=ANY_FLOAT
)
#: Lengths in units of the muscle's max_length: any float mixed with floats over (and a little
#: beyond) the whole geometry; a scalar or an array (m, 1), which broadcasts with every value
#: against every length.
LENGTH_UNITS = st.one_of(ANY_FLOAT, st.floats(0, 1.2))
ANY_LENGTH_UNITS = LENGTH_UNITS | arrays(
    np.float64, st.tuples(st.integers(1, 6), st.just(1)), elements=LENGTH_UNITS
)


def expected_invalid(muscle: MuscleModel, value, length) -> np.ndarray:
    value, length = np.broadcast_arrays(np.asarray(value, float), np.asarray(length, float))
    return ~(
        np.isfinite(value) & np.isfinite(length) & (length > 0) & (length < muscle.max_length)
    )


@examples(2500)
@given(
    st.sampled_from(MUSCLES),
    ANY_VALUE,
    ANY_LENGTH_UNITS,
    st.none() | st.sampled_from(RATES) | ANY_FLOAT,
)
def test_any_float_input_never_raises_and_nan_only_with_invalid_input(
    muscle, value, length_units, rate
):
    length = np.multiply(length_units, muscle.max_length)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        force = muscle.force(value, length, rate)
        pressure = muscle.pressure(value, length, rate)
    invalid = expected_invalid(muscle, value, length)
    for result, served in ((force, force.force), (pressure, pressure.pressure)):
        assert served.shape == invalid.shape and result.flags.dtype == np.uint16
        np.testing.assert_array_equal(flagged(result.flags, Flag.INVALID_INPUT), invalid)
        np.testing.assert_array_equal(np.isnan(served), invalid)
    assert np.all(force.force[~invalid] >= 0)
    assert np.all(
        (pressure.pressure[~invalid] >= 0)
        & (pressure.pressure[~invalid] <= muscle.spec.max_pressure)
    )


# --- bad parameters: ValueError only
# ---------------------------------------------------------------------

JUNK = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.sampled_from([10**400, -(10**400)])
    | ANY_FLOAT
    | st.text(max_size=4)
    | st.complex_numbers(),
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.tuples(inner, inner)
        | st.dictionaries(st.text(max_size=4), inner, max_size=3)
    ),
    max_leaves=6,
)


def numbers(n: int):
    """Lists of n numbers: any float, small ints, and ints a float cannot hold (YAML reads them as
    int).
    """
    return st.lists(
        ANY_FLOAT | st.integers(-10, 10) | st.sampled_from([10**400, 2**63]),
        min_size=n,
        max_size=n,
    )


def value_error_or(build, one_line: bool = True):
    """build() or None when it raises ValueError (with a one-line message); any other exception
    fails the test.
    """
    try:
        return build()
    except ValueError as err:
        assert str(err) and ('\n' not in str(err) or not one_line)
        return None


@examples(750)
@given(
    st.sampled_from(list(MODELS.values())).flatmap(
        lambda m: st.tuples(st.just(m), numbers(m.n_params) | JUNK)
    ),
    st.booleans(),
)
def test_check_params_raises_value_error_only(model_theta, as_array):
    model, theta = model_theta
    if as_array:  # a float array (when numpy can make one) as well as a parameter file's lists
        try:
            theta = np.array(theta, dtype=float).reshape(-1)[: model.n_params]
        except (TypeError, ValueError, OverflowError):
            pass
    one_line = not as_array  # numpy wraps long reprs
    values = value_error_or(lambda: model.check_params(theta), one_line=one_line)
    if values is not None:
        assert values.shape == (model.n_params,) and np.all(np.isfinite(values))


DROP, KEEP = object(), object()  # mutation markers: remove the key / leave the value as it is


def mutations(base: dict, keys: tuple[str, ...]):
    """``base`` with some of ``keys`` replaced by junk or numbers, dropped, or an unknown key
    added.
    """
    change = st.one_of(JUNK, ANY_FLOAT, st.sampled_from([10**400, 0, -1]), st.just(DROP))
    return st.fixed_dictionaries({}, optional=dict.fromkeys(keys + ('unknown',), change)).map(
        lambda edits: {k: v for k, v in (base | edits).items() if v is not DROP}
    )


SPEC = PARAMETERS['DMSP-10-250']['muscle']


@examples(750)
@given(mutations(SPEC, tuple(SPEC)))
def test_muscle_spec_raises_value_error_only(mapping):
    specs = [value_error_or(lambda: MuscleSpec.from_mapping(mapping))]
    if set(mapping) == set(SPEC):
        specs.append(value_error_or(lambda: MuscleSpec(**mapping)))
    for spec in filter(None, specs):
        assert all(
            math.isfinite(v) and v > 0
            for v in (
                spec.nominal_length,
                spec.inner_diameter,
                spec.membrane_thickness,
                spec.max_pressure,
            )
        )
        assert 0 < spec.fiber_angle < math.pi / 2


@examples(750)
@given(ANY_FLOAT, ANY_FLOAT)
def test_domain_raises_value_error_only(low, high):
    domain = value_error_or(lambda: Domain(low, high))
    assert domain is None or 0 < domain.length_min < domain.length_max


MUTATED = [
    mutations(parameters, ('muscle', 'model', 'length_range', 'models'))
    for parameters in PARAMETERS.values()
]
PARAMS = {
    n: st.just(KEEP) | JUNK | numbers(n)
    for n in range(1 + max(m.n_params for m in MODELS.values()))
}


@st.composite
def mangled_parameters(draw):
    """A shipped parameter mapping with top-level entries, one model's params and the length range
    mangled.
    """
    parameters = copy.deepcopy(draw(st.one_of(MUTATED)))
    models = parameters.get('models')
    if isinstance(models, dict) and models:
        entry = models[draw(st.sampled_from(sorted(models)))]
        if isinstance(entry, dict):
            params = draw(
                PARAMS[len(entry['params']) if isinstance(entry.get('params'), list) else 2]
            )
            if params is not KEEP:
                entry['params'] = params
    length_range = draw(PARAMS[2])
    if 'length_range' in parameters and length_range is not KEEP:
        parameters['length_range'] = length_range
    return parameters, draw(st.none() | st.sampled_from(sorted(MODELS)) | st.text(max_size=6))


@examples(750)
@given(mangled_parameters())
def test_muscle_model_raises_value_error_only(case):
    parameters, model = case
    muscle = value_error_or(lambda: muscle_model(parameters, model))
    if muscle is not None:
        assert 0 < muscle.domain.length_min < muscle.domain.length_max
        assert np.all(np.isfinite(muscle.theta))
