"""A simulated pneumatic muscle whose static force is a measured force map (no ROS).

What ``simulator_node`` publishes and what the bag tools record without DDS: at each step, the
pressure follows its target (a commanded pressure, or a triangle sweep over the map's pressures)
with a first-order lag, the length follows a trajectory, and the tension is the truth
(:func:`read_truth`: a shipped map, a user's map CSV with its spec, or an identified muscle's
parameter file), changed over time by an optional :class:`~.truth.Drift`, plus an optional
hysteresis half-gap whose sign is the branch of the length's play operator
(:mod:`~pma_model_ros.core.physics.hysteresis`, the rule model_node follows); Gaussian noise is
added to what is "measured".

The ground truth is not one of the models: the simulator's truth is the measurement itself, so a
model is judged against data it was identified on (and, between the measured points, against a
shape-preserving interpolation of them).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Callable, TypeVar

import numpy as np

from .truth import Drift, GroundTruth, ModelTruth, Truth
from ..files.node_parameters import ParameterSpec, read_only, SPECS
from ..files.param_file import load_muscle
from ..files.shipped_data import MAPPED_MUSCLES, shipped_force_map
from ..files.user_files import read_spec_yaml
from ..identification.force_map import read_force_map_csv
from ..physics.hysteresis import play

T = TypeVar('T')
TRAJECTORIES = ('constant', 'sine', 'sweep', 'steps')
#: Share of each 'steps' period spent moving to the next length (the rest holds it).
STEP_MOVE = 0.25
#: Both simulators' pressure lag [s] toward the commanded pressure.
PRESSURE_TIME_CONSTANT = ParameterSpec(
    'pressure_time_constant',
    'double',
    0.05,
    'first-order time constant toward the commanded pressure',
    's',
    (0.0, 60.0),
)
#: simulator_node's parameters, read at start-up (read-only).
PARAMETERS: tuple[ParameterSpec, ...] = read_only(
    ParameterSpec(
        'muscle',
        'string',
        'DMSP-10-250',
        f'shipped muscle whose measured map is the truth: {", ".join(MAPPED_MUSCLES)} (unless '
        "'map_file' or 'params_file' is set)",
        choices=MAPPED_MUSCLES,
    ),
    ParameterSpec(
        'map_file',
        'string',
        '',
        "a measured force map CSV (pma-model fit --data's format) as the truth, with "
        "'spec_file'; replaces 'muscle'",
    ),
    ParameterSpec(
        'spec_file', 'string', '', "the muscle spec YAML of 'map_file' (pma-model fit --muscle)"
    ),
    ParameterSpec(
        'params_file',
        'string',
        '',
        'a one-muscle parameter file (pma-model fit --out): its identified model as the truth; '
        "replaces 'muscle'",
    ),
    ParameterSpec('rate', 'double', 100.0, 'publishing rate', 'Hz', (1.0, 1000.0)),
    replace(SPECS['ambient_pressure'], description='ambient pressure'),
    ParameterSpec('joint_name', 'string', '', 'JointState entry name (empty: the muscle name)'),
    ParameterSpec(
        'noise.pressure_std',
        'double',
        0.0,
        'standard deviation of the published pressure',
        'Pa',
        (0.0, 1e5),
    ),
    ParameterSpec(
        'noise.length_std',
        'double',
        0.0,
        'standard deviation of the published length',
        'm',
        (0.0, 0.01),
    ),
    ParameterSpec(
        'noise.force_std',
        'double',
        0.0,
        'standard deviation of the published force',
        'N',
        (0.0, 1e3),
    ),
    ParameterSpec('seed', 'integer', 0, 'seed of the noise generator'),
    ParameterSpec(
        'hysteresis_gap',
        'double',
        0.0,
        'half-gap of a hysteresis: + on the lengthening branch, - on the shortening one '
        "(model_node's play operator: core/physics/hysteresis.py), faded out below this force "
        "(Sárosi's DMSP-10-100 branches differ by about 10 % of force)",
        'N',
        (0.0, 1e4),
    ),
    replace(
        SPECS['hysteresis.length_deadband'],
        name='hysteresis_deadband',
        description='the branch changes when the length reverses by more than this',
    ),
    PRESSURE_TIME_CONSTANT,
    ParameterSpec(
        'initial_pressure',
        'double',
        0.0,
        "gauge pressure before any pressure_command ('constant' and 'sine')",
        'Pa',
        (0.0, 5e6),
    ),
    ParameterSpec(
        'trajectory',
        'string',
        'sweep',
        f"length trajectory: {', '.join(TRAJECTORIES)}; 'sweep' and 'steps' also sweep the "
        'pressure until a pressure_command arrives',
        choices=TRAJECTORIES,
    ),
    ParameterSpec(
        'length', 'double', 0.23, "length for the 'constant' trajectory", 'm', (0.0, 10.0)
    ),
    ParameterSpec(
        'length_min', 'double', 0.2, "lower length of the 'sine' trajectory", 'm', (0.0, 10.0)
    ),
    ParameterSpec(
        'length_max', 'double', 0.25, "upper length of the 'sine' trajectory", 'm', (0.0, 10.0)
    ),
    ParameterSpec(
        'period',
        'double',
        4.0,
        "period of the 'sine' and of the 'sweep' length triangle; time per held length of 'steps'",
        's',
        (0.01, 1e4),
    ),
    ParameterSpec(
        'steps',
        'integer',
        6,
        "number of lengths 'steps' holds, evenly over the map's lengths, visited up and down; it "
        f'moves to the next in the first {STEP_MOVE:.0%} of each period (a calibration run)',
    ),
    ParameterSpec(
        'sweep_period',
        'double',
        20.0,
        "period of the 'sweep' pressure triangle over the map's pressures",
        's',
        (0.01, 1e4),
    ),
    ParameterSpec(
        'drift.gain',
        'double',
        1.0,
        "force gain reached at 'drift.start' + 'drift.duration' (1: no drift)",
        '',
        (0.0, 10.0),
    ),
    ParameterSpec(
        'drift.start', 'double', 0.0, 'when the gain leaves 1, after start-up', 's', (0.0, 1e7)
    ),
    ParameterSpec(
        'drift.duration',
        'double',
        0.0,
        'time the gain takes from 1 to drift.gain, linearly (0: a step)',
        's',
        (0.0, 1e7),
    ),
    ParameterSpec(
        'drift.map_file', 'string', '', "a force map CSV that becomes the truth at 'drift.at'"
    ),
    ParameterSpec('drift.spec_file', 'string', '', "the muscle spec YAML of 'drift.map_file'"),
    ParameterSpec(
        'drift.params_file',
        'string',
        '',
        "a one-muscle parameter file whose model becomes the truth at 'drift.at'",
    ),
    ParameterSpec(
        'drift.at',
        'double',
        0.0,
        "when the drift's map or model takes over, after start-up",
        's',
        (0.0, 1e7),
    ),
)


def defaults(**overrides: object) -> dict[str, object]:
    """Every parameter at its default, with ``overrides`` (use '__' for '.':
    ``noise__force_std=1.0``).
    """
    values = {spec.name: spec.default for spec in PARAMETERS}
    for key, value in overrides.items():
        name = key.replace('__', '.')
        if name not in values:
            raise ValueError(f'unknown simulator parameter {name!r}')
        values[name] = value
    return values


def triangle(t: float, period: float) -> tuple[float, float]:
    """Triangle wave 0 -> 1 -> 0 over ``period`` [s]: (value, slope [1/s])."""
    phase = (t / period) % 1.0
    return (2 * phase, 2 / period) if phase < 0.5 else (2 - 2 * phase, -2 / period)


def read_truth(params: dict[str, object], prefix: str = '') -> tuple[str, Truth] | None:
    """The muscle's name and the truth its ``<prefix>map_file`` and ``spec_file`` or
    ``params_file`` name; None if none is set. ValueError, one line naming the parameter, for a
    file that cannot be the truth.
    """
    names = {key: prefix + key for key in ('map_file', 'spec_file', 'params_file')}
    given = {key: str(params[name]) for key, name in names.items() if params[name]}
    if 'params_file' in given and len(given) > 1:
        raise ValueError(
            f"parameters '{names['params_file']}' and '{names['map_file']}'/"
            f"'{names['spec_file']}' both name a truth: set one"
        )
    if given.keys() == {'params_file'}:
        model = _reading(names['params_file'], lambda: load_muscle(given['params_file']))
        return model.spec.name, ModelTruth(model)
    if given and given.keys() != {'map_file', 'spec_file'}:
        raise ValueError(
            f"parameters '{names['map_file']}' and '{names['spec_file']}' go together: a force "
            'map CSV and the spec of its muscle (as pma-model fit --data and --muscle)'
        )
    if not given:
        return None
    spec = _reading(names['spec_file'], lambda: read_spec_yaml(given['spec_file']))
    fmap = _reading(names['map_file'], lambda: read_force_map_csv(given['map_file']))
    where = f'{given["map_file"]}: '
    return spec.name, _reading(names['map_file'], lambda: GroundTruth(fmap), where)


def _reading(name: str, read: Callable[[], T], where: str = '') -> T:
    """``read()``; its ValueError as one line naming the parameter ``name`` (then ``where``)."""
    try:
        return read()
    except ValueError as err:
        raise ValueError(f"parameter '{name}': {where}{err}") from None


def read_drift(params: dict[str, object]) -> Drift:
    """The :class:`~.truth.Drift` of the ``drift.*`` parameters."""
    then = read_truth(params, 'drift.')
    return Drift(
        float(params['drift.gain']),
        float(params['drift.start']),
        float(params['drift.duration']),
        None if then is None else then[1],
        float(params['drift.at']),
    )


@dataclass(frozen=True)
class Readings:
    """What the muscle's sensors report at each of a run of instants (noise included); arrays."""

    pressure: np.ndarray  #: absolute pressure [Pa]
    length: np.ndarray  #: [m]
    rate: np.ndarray  #: length rate [m/s] (noise-free)
    force: np.ndarray  #: measured tension [N]


class SimulatedMuscle:
    """The simulated muscle; ``params`` as :data:`PARAMETERS` (e.g. from :func:`defaults`), times
    in s.
    """

    def __init__(self, params: dict[str, object], start: float) -> None:
        if params['trajectory'] not in TRAJECTORIES:
            raise ValueError(
                f"parameter 'trajectory' must be one of {TRAJECTORIES}, got "
                f'{params["trajectory"]!r}'
            )
        if params['trajectory'] == 'sine' and not params['length_min'] < params['length_max']:
            raise ValueError("parameters 'length_min' < 'length_max' needed for 'sine'")
        if params['trajectory'] == 'steps' and not int(params['steps']) >= 2:
            raise ValueError(f"parameter 'steps' must be >= 2 for 'steps', got {params['steps']}")
        self.name, self.truth = read_truth(params) or (
            str(params['muscle']),
            GroundTruth(shipped_force_map(str(params['muscle']))),
        )
        self.drift = read_drift(params)
        self.params = params
        self.joint = str(params['joint_name'] or self.name)
        self._rng = np.random.default_rng(int(params['seed']))
        self._pressure = float(params['initial_pressure'])  # gauge [Pa]
        self._command: float | None = None  # commanded gauge pressure [Pa]
        self._start = self._last = start
        self._branch, self._anchor = 0.0, math.nan  # hysteresis play operator on the length

    def command(self, absolute: float) -> None:
        """A pressure command [Pa absolute]; non-finite values are ignored."""
        if math.isfinite(absolute):
            self._command = absolute - float(self.params['ambient_pressure'])

    def _length(self, t: float) -> tuple[float, float]:
        """Length [m] and its rate [m/s] at time ``t`` [s] after start."""
        p = self.params
        if p['trajectory'] == 'constant':
            return p['length'], 0.0
        if p['trajectory'] == 'sine':
            mid, amp, w = (
                (p['length_max'] + p['length_min']) / 2,
                (p['length_max'] - p['length_min']) / 2,
                2 * math.pi / p['period'],
            )
            return mid + amp * math.sin(w * t), amp * w * math.cos(w * t)
        low, high = self.truth.lengths[0], self.truth.lengths[-1]
        if p['trajectory'] == 'steps':
            return self._step_length(t, low, high)
        value, slope = triangle(t, p['period'])
        return low + (high - low) * value, (high - low) * slope

    def _step_length(self, t: float, low: float, high: float) -> tuple[float, float]:
        """'steps': the k-th period moves (linearly, in its first STEP_MOVE) from level k-1 to
        level k, then holds.
        """
        n, period = int(self.params['steps']), self.params['period']
        cycle = 2 * (n - 1)

        def level(
            k: int,
        ) -> float:  # offset from ``low`` [m] of the k-th held length: 0, 1, .., n-1, .., 1, 0, ..
            k %= cycle
            return (k if k < n else cycle - k) * (high - low) / (n - 1)

        k, phase = divmod(t / period, 1.0)
        start, end = level(int(k) - 1) if k > 0 else level(0), level(int(k))
        if phase >= STEP_MOVE:
            return low + end, 0.0
        return low + start + (end - start) * phase / STEP_MOVE, (end - start) / (
            STEP_MOVE * period
        )

    def _target(self, t: float) -> float:
        """Gauge pressure [Pa] the muscle is driven toward at time ``t`` [s]."""
        if self._command is not None:
            return self._command
        if self.params['trajectory'] in ('sweep', 'steps'):
            low, high = self.truth.pressures[0], self.truth.pressures[-1]
            return low + (high - low) * triangle(t, self.params['sweep_period'])[0]
        return self.params['initial_pressure']

    def run(self, times: np.ndarray) -> Readings:
        """Advance through the increasing ``times`` [s] and read the sensors at each (force
        evaluated at once).
        """
        p, n = self.params, len(times)
        tau = p['pressure_time_constant']
        state = np.empty((n, 4))  # gauge pressure, length, rate, hysteresis branch
        for i, now in enumerate(times):
            dt, self._last = max(now - self._last, 0.0), now
            t = now - self._start
            self._pressure += (self._target(t) - self._pressure) * (
                1.0 - math.exp(-dt / tau) if tau > 0 else 1.0
            )
            length, rate = self._length(t)
            self._branch, self._anchor = play(
                self._branch, self._anchor, float(length), p['hysteresis_deadband']
            )
            state[i] = (self._pressure, length, rate, self._branch)
        gauge, length, rate, branch = state.T
        force = self.drift.force(self.truth, np.asarray(times) - self._start, gauge, length)
        force += branch * np.minimum(p['hysteresis_gap'], force)
        noise = self._rng.normal(size=(n, 3)) * [
            p['noise.pressure_std'],
            p['noise.length_std'],
            p['noise.force_std'],
        ]
        return Readings(
            gauge + p['ambient_pressure'] + noise[:, 0],
            length + noise[:, 1],
            rate,
            force + noise[:, 2],
        )
