"""Static force models F(p, L) of pneumatic muscles.

Every model here is a polynomial of degree <= 2 in the gauge pressure p at a
fixed length L, so each is written once, as the coefficients

    F_raw(p, L) = q2(L) p^2 + q1(L) p + q0(L)        [N], p in Pa gauge, L in m.

That single form gives the forward force, the closed-form inverse
(:meth:`pma_model_ros.core.physics.muscle_model.Evaluator.pressure`) and the identification
residuals.  Equation numbers refer to Martens & Boblan, Actuators 2017 ("eq. N") and to Sárosi,
"Modelling hysteresis in the force characteristic of the fluidic muscles" ("Sárosi eq. N").  Start
points are the paper's Table 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
import math
from typing import Callable

import numpy as np

from . import elementwise as ew
from . import geometry as geo
from .geometry import MuscleSpec
from ..hints import did_you_mean

Coefficients = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Domain:
    """What a model was identified on, and how it is served outside that.

    Inside [length_min, length_max] x [0, pressure_max] the model is served as identified.
    Outside, if ``extrapolates`` (the served rule of the model, :func:`extrapolates`), the model's
    own value is served in the physical envelope (the braid's
    shortest length to L0, 0 to the rated pressure), flagged EXTRAPOLATED; otherwise the value at
    the nearest identified point, flagged LENGTH_OUT_OF_RANGE or PRESSURE_OUT_OF_RANGE
    (:meth:`~.muscle_model.Evaluator.operating`).
    """

    length_min: float  #: [m]
    length_max: float  #: [m]
    #: highest identified gauge pressure [Pa]; inf: unknown (the rated one)
    pressure_max: float = math.inf
    extrapolates: bool = False  #: the model is credible outside the identified box

    def __post_init__(self) -> None:
        if not (0 < self.length_min < self.length_max):
            raise ValueError(
                f'length range must satisfy 0 < min < max, got [{self.length_min}, '
                f'{self.length_max}]'
            )
        if not self.pressure_max > 0:
            raise ValueError(
                f'identified pressure range must reach above 0 Pa, got {self.pressure_max}'
            )


#: The models served beyond their identified lengths by their own value (in the physical envelope,
#: flagged EXTRAPOLATED); every other model is held at the nearest identified length.  Chosen per
#: model across four muscles by leave-one-muscle-out on the served nested error of the map's edge
#: lengths (``bench/generalisation.py --rules``; docs/calibration.md): for each muscle the rule
#: that wins on the other three.
EXTRAPOLATING = frozenset({'mckibben', 'andrikopoulos', 'hildebrandt', 'martens', 'martens_end'})


def extrapolates(model: str) -> bool:
    """Whether ``fit`` and ``make-config`` serve ``model`` beyond its identified lengths by its own
    value (:data:`EXTRAPOLATING`, :class:`Domain`); its held-out figures judge the force so served.
    """
    return model in EXTRAPOLATING


@dataclass(frozen=True)
class Model:
    """One static force model.

    ``coefficients(theta, spec, domain, length, branch)`` returns (q2, q1, q0)
    with F_raw = q2 p^2 + q1 p + q0.  ``branch`` is +1 (the followed input rising:
    lengthening or filling), -1 (falling: shortening or venting) or 0 (unknown); only
    hysteresis models use it.  ``lower``/``upper`` are the physical parameter bounds used
    by the ``best`` identification protocol.  For many muscles at once, ``theta``
    may be (n_params, n), and the spec's and domain's numbers arrays of n; the
    coefficients broadcast elementwise (:mod:`pma_model_ros.core.physics.muscle_bank`).
    """

    name: str
    equation: str
    param_names: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    coefficients: Callable[..., Coefficients]
    hysteresis: bool = False
    #: whether q2 may be non-zero (eq. 21 only); where not, the nodes skip its two operations
    #: (test_core_models checks that every other model's q2 is 0)
    quadratic: bool = False
    #: indices of the parameters the force is affine in at fixed others (the separable fit,
    #: :mod:`~pma_model_ros.core.identification.separable`; test_core_models checks each)
    linear: tuple[int, ...] = ()
    #: ``prepared(theta, spec, domain)`` -> ``f(length, branch)``: ``coefficients`` within
    #: rounding, with what does not depend on the length computed once and written for few array
    #: operations (None: nothing worth it; test_core_models pins each); see :meth:`prepare`
    prepared: Callable[..., Callable[..., Coefficients]] | None = None

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def prepare(self, theta, spec: MuscleSpec, domain: Domain) -> Callable[..., Coefficients]:
        """``f(length, branch)`` = ``coefficients(theta, spec, domain, length, branch)`` (bit for
        bit, or within rounding where a model has a :attr:`prepared` form), for a muscle (or a
        bank's group) evaluated at many lengths in turn: the nodes call it per message.
        """
        if self.prepared is not None:
            return self.prepared(theta, spec, domain)
        return partial(self.coefficients, theta, spec, domain)

    def check_params(self, theta: object) -> np.ndarray:
        """Return ``theta`` as a float array, or raise ValueError naming the model."""
        try:
            values = np.asarray(theta, dtype=float) if _is_number_list(theta) else None
        except OverflowError:  # an int beyond float range, as YAML reads 400 digits
            values = None
        if values is None or values.shape != (self.n_params,) or not np.all(np.isfinite(values)):
            raise ValueError(
                f'model {self.name!r} needs {self.n_params} finite parameters '
                f'{list(self.param_names)}, got {theta!r}'
            )
        return values


def _is_number_list(theta: object) -> bool:
    items = theta.tolist() if isinstance(theta, np.ndarray) else theta
    return isinstance(items, (list, tuple)) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in items
    )


def _zeros(length: np.ndarray) -> np.ndarray:
    return ew.zeros_like(length)


def _contraction(spec: MuscleSpec, length: np.ndarray) -> np.ndarray:
    """Relative contraction kappa = (L0 - L) / L0 [-]."""
    return (spec.nominal_length - length) / spec.nominal_length


def _mckibben(theta, spec, domain, length, branch) -> Coefficients:
    """Eq. 17, McKibben / Schulte: F = -p dV/dL = p L_F^2 (3 cos^2 Theta - 1) / (4 pi n^2)."""
    return _zeros(length), -geo.volume_slope(spec, length), _zeros(length)


def _andrikopoulos(theta, spec, domain, length, branch) -> Coefficients:
    """Andrikopoulos, eq. 18 (the Tondu-Lopez form, Sárosi eq. 2, with mu = c0, epsilon = c1).

    F = p c0 (pi D0^2 / 4) [3 / tan^2 Theta0 (1 - c1 kappa)^2 - 1 / sin^2 Theta0].
    """
    c0, c1 = theta
    th0 = spec.fiber_angle
    shape = (
        3 / ew.tan(th0) ** 2 * (1 - c1 * _contraction(spec, length)) ** 2 - 1 / ew.sin(th0) ** 2
    )
    return _zeros(length), c0 * math.pi * spec.inner_diameter**2 / 4 * shape, _zeros(length)


def _sarosi_terms(theta, spec, length) -> tuple[np.ndarray, np.ndarray]:
    c0, c1, c2, d0, d1, d2 = theta
    kappa = _contraction(spec, length)
    growth = ew.exp(c2 * kappa)
    return c0 * growth + d0 * kappa + d1, c1 * growth + d2


def _sarosi(theta, spec, domain, length, branch) -> Coefficients:
    """Sárosi, eq. 19 (identical to Sárosi eq. 3 in SI units).

    F = (c0 p + c1) exp(c2 kappa) + p (d0 kappa + d1) + d2, kappa = (L0 - L) / L0.
    """
    q1, q0 = _sarosi_terms(theta, spec, length)
    return _zeros(length), q1, q0


def _by_branch(branch, rising: tuple, falling: tuple) -> tuple:
    """``rising`` where ``branch`` is +1, ``falling`` where -1, their mean where 0 (unknown)."""
    w_up = (1 + ew.clip(ew.asarray(branch), -1.0, 1.0)) / 2
    return tuple(w_up * u + (1 - w_up) * lo for u, lo in zip(rising, falling))


def _sarosi_hysteresis(theta, spec, domain, length, branch) -> Coefficients:
    """Sárosi eq. 3 with a branch per direction of the followed input (length or pressure).

    ``theta`` = 6 parameters of the rising branch (+1: lengthening or filling) then 6 of the
    falling one (-1: shortening or venting), each in the SI form of eq. 19; which is the upper
    is the data's.  An unknown branch (0) gives the mean of both.
    """
    up1, up0 = _sarosi_terms(theta[:6], spec, length)
    lo1, lo0 = _sarosi_terms(theta[6:], spec, length)
    return _zeros(length), *_by_branch(branch, (up1, up0), (lo1, lo0))


def _hildebrandt(theta, spec, domain, length, branch) -> Coefficients:
    """Hildebrandt, eq. 20: F = p sum_{j<=2} c_j L^j - (sum_{j<=3} d_j L^j + d4 L^(2/3))."""
    c0, c1, c2, d0, d1, d2, d3, d4 = theta
    area = c0 + c1 * length + c2 * length**2
    counter = d0 + d1 * length + d2 * length**2 + d3 * length**3 + d4 * ew.cbrt(length) ** 2
    return _zeros(length), area, -counter


def _wickramatunge(theta, spec, domain, length, branch) -> Coefficients:
    """Wickramatunge, eq. 21: F = (c3 p^2 + c2 p dL + c1 dL^2 + c0) dL, dL = L - min(L).

    min(L) is the shortest length of the identified map (``domain.length_min``).
    """
    c0, c1, c2, c3 = theta
    dl = length - domain.length_min
    return c3 * dl, c2 * dl**2, (c1 * dl**2 + c0) * dl


def _martens(theta, spec, domain, length, branch) -> Coefficients:
    """Martens, eqs. 14-16: F = -p dV/dL + F_PE dD/dL - F_L, written as the paper writes it (the
    identification evaluates it; the nodes evaluate :func:`_martens_prepared`).

    E_RU(L) = c3 L^3 + c2 L^2 + c1 L + c0 [Pa] (eq. 15); the braid angle is
    corrected to Theta0 + d0 [rad] (eq. 16); F_PE = E (D - D0)/D0 H0 L pi
    (eqs. 11, 13) and F_L = E (L - L0)/L0 H0 pi D(L) (eqs. 10, 12).
    """
    c0, c1, c2, c3, d0 = theta
    modulus = ((c3 * length + c2) * length + c1) * length + c0
    dia, dia_slope, volume_slope = geo.braid(spec, length, spec.fiber_angle + d0)
    f_pe = (
        modulus
        * (dia - spec.inner_diameter)
        / spec.inner_diameter
        * spec.membrane_thickness
        * length
        * math.pi
    )
    f_l = (
        modulus
        * (length - spec.nominal_length)
        / spec.nominal_length
        * spec.membrane_thickness
        * math.pi
        * dia
    )
    return _zeros(length), -volume_slope, f_pe * dia_slope - f_l


def _martens_prepared(theta, spec, domain) -> Callable[..., Coefficients]:
    """:func:`_martens` as ``f(length, branch)`` for the nodes (:meth:`Model.prepare`), equal to
    it within rounding: what does not depend on the length computed once, and the length terms
    rearranged for 21 array operations per call instead of 32.  With D = r / (n pi),
    dD/dL = -L / (n pi r), r = sqrt(L_F^2 - L^2) (eq. 2) and -dV/dL = (3 L^2 - L_F^2) /
    (4 pi n^2) (eq. 4): q0 = (E H0 / n) (L^2 / r - L^2 / (n pi D0) - (L - L0) r / L0).
    """
    c0, c1, c2, c3, d0 = theta
    lf_sq, n_pi, four_pi_n_sq = geo.braid_constants(spec, spec.fiber_angle + d0)
    scale = math.pi * spec.membrane_thickness / n_pi  # H0 / n
    k0, k1, k2, k3 = c0 * scale, c1 * scale, c2 * scale, c3 * scale
    inverse_d0, l0 = 1 / (n_pi * spec.inner_diameter), spec.nominal_length
    inverse_l0 = 1 / l0
    volume_sq, volume_0 = _volume_terms(lf_sq, four_pi_n_sq)

    def coefficients(length, branch) -> Coefficients:
        # (no Python number meets an array here: that costs more than an array's operation)
        length_sq = length * length
        root = ew.sqrt(lf_sq - length_sq)
        modulus = ((k3 * length + k2) * length + k1) * length + k0
        shape = length_sq / root - inverse_d0 * length_sq - (length - l0) * root * inverse_l0
        return _zeros(length), volume_sq * length_sq - volume_0, modulus * shape

    return coefficients


def _volume_terms(lf_sq, four_pi_n_sq) -> tuple:
    """(a, b) of the pressure term -dV/dL = a L^2 - b [m^2] (eq. 4)."""
    return 3 / four_pi_n_sq, lf_sq / four_pi_n_sq


def _end_length(spec: MuscleSpec, end_factor, length):
    """The braid length [m] of the pressure term with an end factor a: L0 - a (L0 - L), the
    contraction scaled by a (Tondu & Lopez's end-effect correction of a braid whose ends are held
    at their rest diameter).
    """
    return spec.nominal_length - end_factor * (spec.nominal_length - length)


def _martens_end(theta, spec, domain, length, branch) -> Coefficients:
    """Martens, eqs. 14-16, with the pressure term -p dV/dL of the braid at :func:`_end_length`
    (end factor ``a`` = theta[5]; a = 1 is eq. 14); the elastic terms as in :func:`_martens`.
    """
    q2, _, q0 = _martens(theta[:5], spec, domain, length, branch)
    end = _end_length(spec, theta[5], length)
    return q2, -geo.volume_slope(spec, end, spec.fiber_angle + theta[4]), q0


def _martens_end_prepared(theta, spec, domain) -> Callable[..., Coefficients]:
    """:func:`_martens_end` for the nodes, as :func:`_martens_prepared` for :func:`_martens`."""
    martens = _martens_prepared(theta[:5], spec, domain)
    end_factor = theta[5]
    lf_sq, _, four_pi_n_sq = geo.braid_constants(spec, spec.fiber_angle + theta[4])
    volume_sq, volume_0 = _volume_terms(lf_sq, four_pi_n_sq)

    def coefficients(length, branch) -> Coefficients:
        q2, _, q0 = martens(length, branch)
        end = _end_length(spec, end_factor, length)
        return q2, volume_sq * (end * end) - volume_0, q0

    return coefficients


_BIG = 1e12
MODELS: dict[str, Model] = {
    m.name: m
    for m in (
        Model('mckibben', 'eq. 17', (), (), (), (), _mckibben),
        Model(
            'andrikopoulos',
            'eq. 18',
            ('c0', 'c1'),
            (1e-5, 1e-5),
            (0.0, 0.0),
            (10.0, 10.0),
            _andrikopoulos,
            linear=(0,),
        ),
        Model(
            'wickramatunge',
            'eq. 21',
            ('c0', 'c1', 'c2', 'c3'),
            (1.0, 1.0, 1e-5, 1e-10),
            (-_BIG,) * 4,
            (_BIG,) * 4,
            _wickramatunge,
            quadratic=True,
            linear=(0, 1, 2, 3),
        ),
        Model(
            'hildebrandt',
            'eq. 20',
            ('c0', 'c1', 'c2', 'd0', 'd1', 'd2', 'd3', 'd4'),
            (1e-5, 1e-5, 1e-5, 1.0, 1.0, 1.0, 1.0, 1.0),
            (-_BIG,) * 8,
            (_BIG,) * 8,
            _hildebrandt,
            linear=tuple(range(8)),
        ),
        Model(
            'sarosi',
            'eq. 19',
            ('c0', 'c1', 'c2', 'd0', 'd1', 'd2'),
            (1e-5, 1.0, 1.0, 1e-5, 1e-5, 1.0),
            (-_BIG, -_BIG, -100.0, -_BIG, -_BIG, -_BIG),
            (_BIG, _BIG, 100.0, _BIG, _BIG, _BIG),
            _sarosi,
            linear=(0, 1, 3, 4, 5),
        ),
        Model(
            'martens',
            'eqs. 14-16',
            ('c0', 'c1', 'c2', 'c3', 'd0'),
            (1e6, 1e6, 1e6, 1e6, 0.0),
            (-_BIG,) * 4 + (-0.35,),
            (_BIG,) * 4 + (0.35,),
            _martens,
            linear=(0, 1, 2, 3),
            prepared=_martens_prepared,
        ),
        Model(
            'martens_end',
            'eqs. 14-16, end factor',
            ('c0', 'c1', 'c2', 'c3', 'd0', 'a'),
            (1e6, 1e6, 1e6, 1e6, 0.0, 1.0),
            (-_BIG,) * 4 + (-0.35, 1.0),
            (_BIG,) * 4 + (0.35, 1.5),
            _martens_end,
            linear=(0, 1, 2, 3),
            prepared=_martens_end_prepared,
        ),
        Model(
            'sarosi_hysteresis',
            'Sárosi eq. 3, a branch per direction',
            tuple(
                f'{b}_{n}'
                for b in ('rising', 'falling')
                for n in ('c0', 'c1', 'c2', 'd0', 'd1', 'd2')
            ),
            (),
            (),
            (),
            _sarosi_hysteresis,
            hysteresis=True,
        ),
    )
}
# Tondu-Lopez (Sárosi eq. 2) is the same function as eq. 18: one implementation, two names.
ALIASES = {'tondu_lopez': 'andrikopoulos'}
# The models of the paper's Table 3, in its column order.
TABLE3_MODELS = ('mckibben', 'andrikopoulos', 'wickramatunge', 'hildebrandt', 'sarosi', 'martens')


def get_model(name: object) -> Model:
    """Look a model up by name (case-insensitive, aliases allowed)."""
    key = str(name).strip().lower()
    key = ALIASES.get(key, key)
    if key not in MODELS:
        known = sorted(MODELS) + sorted(ALIASES)
        raise ValueError(
            f'unknown model {name!r}{did_you_mean(key, known)}; known models: {", ".join(known)}'
        )
    return MODELS[key]


def force_raw(
    model: Model,
    theta: np.ndarray,
    spec: MuscleSpec,
    domain: Domain,
    pressure: np.ndarray,
    length: np.ndarray,
    branch: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Unclipped model force F_raw(p, L) [N]; negative where the muscle would push."""
    pressure, length = np.broadcast_arrays(np.asarray(pressure, float), np.asarray(length, float))
    q2, q1, q0 = model.coefficients(theta, spec, domain, length, branch)
    return (q2 * pressure + q1) * pressure + q0


# --- Length derivatives of the coefficients (joint stiffness, pma_model_ros.core.physics.joint)
# ----------------------- Each returns (dq2/dL, dq1/dL, dq0/dL) with the arguments of
# ``Model.coefficients``: analytic, so that dF/dL = dq2/dL p^2 + dq1/dL p + dq0/dL at fixed
# pressure.  Checked against finite differences in test/test_core_models.py.


def _mckibben_slopes(theta, spec, domain, length, branch) -> Coefficients:
    """q1 = -dV/dL = -(L_F^2 - 3 L^2) / (4 pi n^2): dq1/dL = 6 L / (4 pi n^2)."""
    n = geo.turns(spec)
    return _zeros(length), 6 * length / (4 * math.pi * n**2), _zeros(length)


def _andrikopoulos_slopes(theta, spec, domain, length, branch) -> Coefficients:
    c0, c1 = theta
    th0 = spec.fiber_angle
    factor = 1 - c1 * _contraction(spec, length)  # d kappa / dL = -1 / L0
    slope = (
        c0
        * math.pi
        * spec.inner_diameter**2
        / 4
        * 6
        * c1
        * factor
        / (ew.tan(th0) ** 2 * spec.nominal_length)
    )
    return _zeros(length), slope, _zeros(length)


def _sarosi_term_slopes(theta, spec, length) -> tuple[np.ndarray, np.ndarray]:
    c0, c1, c2, d0, d1, d2 = theta
    growth = ew.exp(c2 * _contraction(spec, length))
    return -(c0 * c2 * growth + d0) / spec.nominal_length, -c1 * c2 * growth / spec.nominal_length


def _sarosi_slopes(theta, spec, domain, length, branch) -> Coefficients:
    s1, s0 = _sarosi_term_slopes(theta, spec, length)
    return _zeros(length), s1, s0


def _sarosi_hysteresis_slopes(theta, spec, domain, length, branch) -> Coefficients:
    up1, up0 = _sarosi_term_slopes(theta[:6], spec, length)
    lo1, lo0 = _sarosi_term_slopes(theta[6:], spec, length)
    return _zeros(length), *_by_branch(branch, (up1, up0), (lo1, lo0))


def _hildebrandt_slopes(theta, spec, domain, length, branch) -> Coefficients:
    c0, c1, c2, d0, d1, d2, d3, d4 = theta
    counter = d1 + 2 * d2 * length + 3 * d3 * length**2 + 2 / 3 * d4 / ew.cbrt(length)
    return _zeros(length), c1 + 2 * c2 * length, -counter


def _wickramatunge_slopes(theta, spec, domain, length, branch) -> Coefficients:
    c0, c1, c2, c3 = theta
    dl = length - domain.length_min
    return c3 + _zeros(length), 2 * c2 * dl, 3 * c1 * dl**2 + c0


def _martens_slopes(theta, spec, domain, length, branch) -> Coefficients:
    """Product rule on q0 = F_PE dD/dL - F_L, with d2D/dL2 = -L_F^2 / (n pi root^3), root =
    sqrt(L_F^2 - L^2).
    """
    c0, c1, c2, c3, d0 = theta
    angle = spec.fiber_angle + d0
    lf, n = geo.fiber_length(spec, angle), geo.turns(spec, angle)
    modulus = ((c3 * length + c2) * length + c1) * length + c0
    modulus_slope = (3 * c3 * length + 2 * c2) * length + c1
    dia, dia_slope, _ = geo.braid(spec, length, angle)
    root = ew.sqrt(lf**2 - length**2)
    dia_curve = -(lf**2) / (n * math.pi * root**3)
    d0_, h0, l0 = spec.inner_diameter, spec.membrane_thickness, spec.nominal_length
    f_pe = modulus * (dia - d0_) / d0_ * h0 * length * math.pi
    f_pe_slope = (
        math.pi
        * h0
        / d0_
        * (
            modulus_slope * (dia - d0_) * length
            + modulus * dia_slope * length
            + modulus * (dia - d0_)
        )
    )
    f_l_slope = (
        math.pi
        * h0
        / l0
        * (
            modulus_slope * (length - l0) * dia
            + modulus * dia
            + modulus * (length - l0) * dia_slope
        )
    )
    return (
        _zeros(length),
        _pressure_term_slope(n, length),
        f_pe_slope * dia_slope + f_pe * dia_curve - f_l_slope,
    )


def _pressure_term_slope(turns: float, length):
    """d(-dV/dL)/dL = 6 L / (4 pi n^2) [m] of a braid of ``turns`` n at ``length`` [m] (eq. 4)."""
    return 6 * length / (4 * math.pi * turns**2)


def _martens_end_slopes(theta, spec, domain, length, branch) -> Coefficients:
    """Martens' slopes, with dq1/dL = a q1'(L0 - a (L0 - L)) (chain rule)."""
    end_factor = theta[5]
    q2, _, q0 = _martens_slopes(theta[:5], spec, domain, length, branch)
    end = _end_length(spec, end_factor, length)
    turns = geo.turns(spec, spec.fiber_angle + theta[4])
    return q2, end_factor * _pressure_term_slope(turns, end), q0


#: model name -> analytic (dq2/dL, dq1/dL, dq0/dL), same arguments as ``Model.coefficients``.
SLOPES: dict[str, Callable[..., Coefficients]] = {
    'mckibben': _mckibben_slopes,
    'andrikopoulos': _andrikopoulos_slopes,
    'wickramatunge': _wickramatunge_slopes,
    'hildebrandt': _hildebrandt_slopes,
    'sarosi': _sarosi_slopes,
    'martens': _martens_slopes,
    'martens_end': _martens_end_slopes,
    'sarosi_hysteresis': _sarosi_hysteresis_slopes,
}


def coefficient_slopes(
    model: Model, theta, spec: MuscleSpec, domain: Domain, length, branch=0.0
) -> Coefficients:
    """(dq2/dL, dq1/dL, dq0/dL) of ``model`` at ``length`` [m]: [N/(Pa^2 m)], [N/(Pa m)], [N/m]."""
    return SLOPES[model.name](theta, spec, domain, length, branch)
