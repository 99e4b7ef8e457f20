"""The nodes' parameters as declarative tables of :class:`ParameterSpec` (no ROS): model_node's and
joint_node's.

Each row gives a parameter's name, type, default, unit, range, description and whether the node
ever changes it.  Every node declares its ROS parameters (descriptors with ranges, read-only flags)
from such a table (:mod:`pma_model_ros.nodes.parameters`): model_node from :data:`PARAMETERS`,
joint_node from :data:`JOINT_NODE_PARAMETERS`, :data:`JOINT_PARAMETERS` and
:data:`JOINT_MUSCLE_PARAMETERS`, the simulators from :mod:`~pma_model_ros.core.simulation.muscle`'s
and :mod:`~pma_model_ros.core.simulation.joint`'s.  The core checks values against the same ranges
(:meth:`ParameterSpec.check`, used by :class:`~pma_model_ros.core.runtime.engine.Config` and the
engine), and docs/nodes.md's model_node table is :func:`markdown_table` (a test compares them).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
import re

from ..hints import pressure_hint
from ..physics.geometry import STANDARD_ATMOSPHERE
from ..physics.hysteresis import DEFAULT_DEADBANDS, DEFAULT_FOLLOW
from ..physics.hysteresis import INPUTS as HYSTERESIS_INPUTS
from ..physics.models import ALIASES, MODELS

#: [Pa] The ambient (absolute) pressures on Earth, with a margin: below the summit of Mount Everest
#: (ISO 2533:1975 standard atmosphere at 8848 m: 31.4 kPa; measured there: 33.7 kPa, J. B. West,
#: J. Appl. Physiol. 86 (1999) 1062) and above the highest sea-level pressure on record (WMO:
#: 1084.8 hPa, Tosontsengel, Mongolia, 2001).  A value in bar, kPa, psi or hPa lies outside.
AMBIENT_PRESSURES = (30e3, 120e3)
#: Pairing rules of the engine (see :mod:`pma_model_ros.core.runtime.engine`).
PAIRINGS = ('every_input', 'approximate_time')
#: Input modes of a node serving several muscles.
INPUT_MODES = ('per_muscle', 'combined')
#: Executors a node can spin on (see :mod:`pma_model_ros.nodes.startup`).
EXECUTORS = ('single', 'events')
#: What a FluidPressure's ``fluid_pressure`` holds: absolute (the message's definition) or gauge
#: pressure.
PRESSURE_REFERENCES = ('absolute', 'gauge')
#: Where joint_node reads the muscles' pressures: a FluidPressure per muscle, or one JointState.
PRESSURE_INPUTS = ('per_muscle', 'joint_state')
#: The arrays of a sensor_msgs/JointState.
JOINT_STATE_FIELDS = ('position', 'velocity', 'effort')


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter: ``default`` None means required (from the parameter file)."""

    name: str
    kind: str  #: ``double``, ``integer``, ``string``, ``bool``, ``double[]`` or ``string[]``
    default: object
    description: str
    unit: str = ''
    limits: tuple[float, float] | None = None  #: inclusive [min, max]
    choices: tuple[str, ...] = ()
    per_muscle: bool = False  #: with ``muscles:``, under ``<name>.``; else node-wide
    read_only: bool = False  #: fixed at start-up: the node never changes it

    def check(self, value: object) -> object:
        """``value`` if it is one of this parameter's; else ValueError naming the parameter, its
        range and unit.
        """
        if self.kind == 'double':
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(
                    f"parameter '{self.name}' must be a number [{self.unit}], got {value!r}"
                )
            low, high = self.limits or (-math.inf, math.inf)
            if not low <= value <= high:  # NaN too
                hint = pressure_hint(value, self.limits) if self.unit.startswith('Pa') else ''
                raise ValueError(
                    f"parameter '{self.name}' must be in [{low:g}, {high:g}] {self.unit}, got "
                    f'{value!r}' + (f' ({hint})' if hint else '')
                )
            return float(value)
        if self.kind == 'integer' and (isinstance(value, bool) or not isinstance(value, int)):
            raise ValueError(f"parameter '{self.name}' must be an integer, got {value!r}")
        if self.choices and value not in self.choices:
            noun = self.name.rsplit('_', 1)[-1]
            raise ValueError(
                f"parameter '{self.name}': unknown {noun} {value!r}; one of "
                f'{", ".join(self.choices)}'
            )
        return value


def read_only(*specs: ParameterSpec) -> tuple[ParameterSpec, ...]:
    """``specs`` as the table of a node that reads its parameters at start-up only."""
    return tuple(replace(spec, read_only=True) for spec in specs)


#: Every name ``model`` accepts: the registry's models and aliases.
_MODEL_NAMES = ', '.join([*MODELS, *(f'{alias} (= {name})' for alias, name in ALIASES.items())])
#: Every parameter of model_node, in docs/nodes.md's order.
PARAMETERS: tuple[ParameterSpec, ...] = (
    ParameterSpec(
        'muscles',
        'string[]',
        [],
        'names of the muscles this node serves, each with the per-muscle '
        'parameters under `<name>.` (empty: one muscle, parameters at the top level)',
        read_only=True,
    ),
    ParameterSpec(
        'input_mode',
        'string',
        'per_muscle',
        'with `muscles`: `per_muscle` (topics under `<name>/`) or '
        '`combined` (one JointState of every muscle per topic)',
        choices=INPUT_MODES,
        read_only=True,
    ),
    ParameterSpec(
        'muscle.name',
        'string',
        None,
        'catalogue name of the muscle, e.g. DMSP-10-250',
        per_muscle=True,
    ),
    ParameterSpec(
        'muscle.nominal_length',
        'double',
        None,
        'initial (unpressurised) length L0',
        'm',
        (0.0, 10.0),
        per_muscle=True,
    ),
    ParameterSpec(
        'muscle.inner_diameter',
        'double',
        None,
        'initial inner diameter D0',
        'm',
        (0.0, 1.0),
        per_muscle=True,
    ),
    ParameterSpec(
        'muscle.membrane_thickness',
        'double',
        None,
        'initial membrane thickness H0',
        'm',
        (0.0, 1.0),
        per_muscle=True,
    ),
    ParameterSpec(
        'muscle.fiber_angle',
        'double',
        None,
        'initial braid angle Θ0 to the muscle axis',
        'rad',
        (0.0, math.pi / 2),
        per_muscle=True,
    ),
    ParameterSpec(
        'muscle.max_pressure',
        'double',
        None,
        'rated gauge pressure; the inverse never commands more',
        'Pa gauge',
        (0.0, 5e6),
        per_muscle=True,
    ),
    ParameterSpec(
        'model',
        'string',
        None,
        f'force model in use, a key of `models`: {_MODEL_NAMES}',
        per_muscle=True,
    ),
    ParameterSpec(
        'length_range',
        'double[]',
        None,
        '[min, max] length the models were identified on (validity domain)',
        'm',
        per_muscle=True,
    ),
    ParameterSpec(
        'pressure_range',
        'double[]',
        [],
        '[0, max] gauge pressure the models were identified on (empty: '
        'up to `muscle.max_pressure`)',
        'Pa gauge',
        per_muscle=True,
    ),
    ParameterSpec(
        'models.<model>.params',
        'double[]',
        None,
        "identified parameters of each model (SI units); only the selected `model`'s block is "
        "declared (switching `model` declares the new one's, from the file or as last set)",
        per_muscle=True,
    ),
    ParameterSpec(
        'models.<model>.extrapolates',
        'bool',
        False,
        "serve the model's own value outside the identified "
        'ranges, flagged EXTRAPOLATED (else the nearest identified point, flagged out of range); '
        '`fit` and `make-config` set it by the model (martens: true), the rule its held-out '
        'errors judge',
        per_muscle=True,
    ),
    ParameterSpec(
        'models.<model>.{nominal_length, pressure_offset}',
        'double',
        None,
        'geometry calibration of a fit by `pma-model fit`: effective rest length L0 [m] (replaces '
        '`muscle.nominal_length` for this model) and pressure-sensor offset [Pa] (the model sees '
        'gauge pressure − offset); absent: `muscle.nominal_length` and 0',
        'm, Pa',
        per_muscle=True,
    ),
    ParameterSpec(
        'hysteresis.input',
        'string',
        DEFAULT_FOLLOW.input,
        "what a hysteresis model's branch follows: `length` "
        "(lengthening +1 / shortening −1, Sárosi's loop) or `pressure` (filling +1 / venting −1)",
        choices=HYSTERESIS_INPUTS,
        per_muscle=True,
    ),
    ParameterSpec(
        'hysteresis.length_deadband',
        'double',
        DEFAULT_DEADBANDS['length'],
        'the branch changes when the length reverses by '
        'more than this from the extreme of its run (play operator)',
        'm',
        (0.0, 0.1),
        per_muscle=True,
    ),
    ParameterSpec(
        'hysteresis.pressure_deadband',
        'double',
        DEFAULT_DEADBANDS['pressure'],
        'the same, for `hysteresis.input: pressure`',
        'Pa',
        (0.0, 1e6),
        per_muscle=True,
    ),
    ParameterSpec(
        'joint_name',
        'string',
        '',
        'JointState entry of this muscle (empty: `muscle.name`; with '
        "`muscles`: the muscle's name)",
        per_muscle=True,
    ),
    ParameterSpec(
        'frame_id',
        'string',
        '',
        "header.frame_id of `force_estimate` and `pressure_command`: the muscle's frame, its x "
        'axis along the muscle, so that force.x is the tension (empty: `joint_name` lower-cased, '
        'other characters than [a-z0-9_] replaced by `_`, e.g. `dmsp_10_250`)',
        per_muscle=True,
    ),
    ParameterSpec(
        'hardware_id',
        'string',
        '',
        "the device: `hardware_id` of the muscle's /diagnostics status (empty: "
        '`/<namespace>/model_node/<joint_name>`, unique per node)',
        per_muscle=True,
    ),
    ParameterSpec(
        'ambient_pressure',
        'double',
        STANDARD_ATMOSPHERE,
        'ambient pressure; gauge = `fluid_pressure` − `ambient_pressure`',
        'Pa absolute',
        AMBIENT_PRESSURES,
    ),
    ParameterSpec(
        'pressure_reference',
        'string',
        'absolute',
        'what `fluid_pressure` of `pressure` and '
        "`pressure_command` holds: `absolute` (the message's definition) or `gauge` (sensors that "
        'publish gauge)',
        choices=PRESSURE_REFERENCES,
    ),
    ParameterSpec(
        'max_input_age',
        'double',
        0.1,
        'inputs whose stamp differs from the node clock by more than this are stale',
        's',
        (1e-3, 3600.0),
    ),
    ParameterSpec(
        'pairing',
        'string',
        'every_input',
        'when to estimate: `every_input` (each valid input, with '
        'the newest other one) or `approximate_time` (once per new pressure and new length whose '
        'stamps lie within `pairing_slop`)',
        choices=PAIRINGS,
        read_only=True,
    ),
    ParameterSpec(
        'pairing_slop',
        'double',
        0.0005,
        '`approximate_time`: largest stamp difference of a pressure and a length paired',
        's',
        (0.0, 1.0),
        read_only=True,
    ),
    ParameterSpec(
        'max_queue_delay',
        'double',
        0.005,
        'an input that waited longer than this since its publisher wrote it (less the usual '
        'transport time) is not answered: the newest input waiting behind it is, the others are '
        'skipped (counted `skipped behind`), so a node that falls behind answers its newest '
        'inputs (`executor: single`; the events executor passes no message info)',
        's',
        (1e-4, 3600.0),
        read_only=True,
    ),
    ParameterSpec(
        'max_answer_delay',
        'double',
        0.02,
        'an answer published longer than this after its input would have arrived holds the '
        'level at WARN (`answers late`) for a second (`executor: single`)',
        's',
        (1e-4, 3600.0),
        read_only=True,
    ),
    ParameterSpec(
        'forward_command_topic',
        'string',
        '',
        "topic of every muscle's pressure command [Pa, as `pressure_command`] as one "
        'std_msgs/Float64MultiArray per force command that commanded one, in '
        "`forward_command_order` (what ros2_control's forward_command_controller takes on "
        '`<controller>/commands`); empty: none',
        read_only=True,
    ),
    ParameterSpec(
        'forward_command_order',
        'string[]',
        [],
        'the muscles of the `forward_command_topic` array by `joint_name`, in order (the '
        "controller's `joints`; some or all of this node's muscles, each once); empty: every "
        'muscle in the order of `muscles`',
        read_only=True,
    ),
    ParameterSpec(
        'residual.enabled',
        'bool',
        False,
        "subscribe each muscle's measured force (`measured_force`, combined: "
        '`measured_forces`), pair it by stamp with the estimate of the same inputs and report '
        'measured - served over `residual.window` against the held-out band in /diagnostics '
        '(model drift); the samples feed `reidentify.*`; false: no subscription',
        read_only=True,
    ),
    ParameterSpec(
        'residual.window',
        'double',
        10.0,
        'the rolling window of the residual figures and level',
        's',
        (0.1, 3600.0),
        read_only=True,
    ),
    ParameterSpec(
        'residual.warn_ratio',
        'double',
        1.0,
        "WARN (model drift) while the window's RMS residual is above this times the band",
        '',
        (0.1, 100.0),
        read_only=True,
    ),
    ParameterSpec(
        'residual.error_ratio',
        'double',
        2.0,
        "ERROR while the window's RMS residual is above this times the band (>= `warn_ratio`)",
        '',
        (0.1, 100.0),
        read_only=True,
    ),
    ParameterSpec(
        'residual.hysteresis',
        'double',
        0.2,
        'a level is left only once the ratio is below its threshold times (1 - this)',
        '',
        (0.0, 0.9),
        read_only=True,
    ),
    ParameterSpec(
        'reidentify.enabled',
        'bool',
        False,
        'identify each muscle again from its measured samples once they cover its identified '
        'pressures and lengths (`reidentify.*`), off the estimation path, and serve the result '
        "if it beats the served parameters on samples not fitted; false: the file's parameters",
    ),
    ParameterSpec(
        'reidentify.freeze',
        'bool',
        False,
        "true: serve the file's parameters again and collect nothing until false",
    ),
    ParameterSpec(
        'reidentify.save_file',
        'string',
        '',
        'where the `save_parameters` service writes the served parameters (several muscles: '
        '`<stem>.<muscle>.yaml`); empty: `<joint_name>_parameters.yaml` in the ROS log directory',
    ),
    ParameterSpec(
        'reidentify.per_cell',
        'integer',
        3,
        "samples for a cell of the 8 x 5 pressure x length grid over the samples' box to "
        'count as covered (>= 1)',
        read_only=True,
    ),
    ParameterSpec(
        'reidentify.cell_share',
        'double',
        0.6,
        "share of the cells of the samples' pressure x length box covered for enough coverage "
        '(also: covered cells at `reidentify.lengths` lengths, the box spanning half the top '
        'pressure and 5 % of the rest length)',
        '',
        (0.05, 1.0),
        read_only=True,
    ),
    ParameterSpec(
        'reidentify.lengths',
        'integer',
        3,
        'length bins (of 5) with a covered cell for enough coverage (1 to 5)',
        read_only=True,
    ),
    ParameterSpec(
        'reidentify.check_every',
        'integer',
        4,
        'every n-th sample is a check sample, never fitted, that a new fit must beat the served '
        'parameters on (>= 2)',
        read_only=True,
    ),
    ParameterSpec(
        'executor',
        'string',
        'single',
        'rclpy executor spinning the node: `single` '
        '(SingleThreadedExecutor) or `events` (the experimental EventsExecutor)',
        choices=EXECUTORS,
        read_only=True,
    ),
    ParameterSpec(
        'autostart',
        'bool',
        True,
        'configure and activate the node at start-up (a bad parameter ends the process); '
        '`false`: wait unconfigured for a lifecycle manager (`<node>/change_state`)',
        read_only=True,
    ),
)
SPECS = {spec.name: spec for spec in PARAMETERS}
#: Declared by every node's process, not by its parameter code: ``executor`` (nodes/startup.py;
#: the managed nodes' shell too, nodes/managed.py) and ``autostart`` (nodes/managed.py).
PROCESS_PARAMETERS = ('executor', 'autostart')
#: The entries of a model's block ``models.<model>.``: its ROS parameters (the selected model's)...
MODEL_BLOCK = ('params', 'extrapolates', 'nominal_length', 'pressure_offset')
#: ... and its identification results, read from the parameter file into each muscle's
#: diagnostics (:func:`~pma_model_ros.core.files.param_file.identification`), not ROS parameters.
IDENTIFICATION = (
    'objective',
    'err',
    'rmse',
    'r2',
    'cv_err',
    'interior_cv_err',
    'edge_cv_err',
    'held_out',
)


def names_of(table: tuple[ParameterSpec, ...]) -> tuple[str, ...]:
    """The parameter names of ``table``."""
    return tuple(p.name for p in table)


def frame_of(name: str) -> str:
    """The ``frame_id`` of a muscle of joint (JointState) name ``name`` that sets none: ``name``
    lower-cased, each character other than ``[a-z0-9_]`` replaced by ``_`` (``DMSP-10-250`` →
    ``dmsp_10_250``), a name a URDF link and tf2 take as it is; what ``fit`` and ``make-config``
    write into a parameter file.
    """
    return re.sub('[^a-z0-9_]', '_', name.lower())


def topic_prefixes(names: list[str]) -> list[str]:
    """The topic namespace of each muscle of model_node (per_muscle mode): ``<name>/``, or '' for
    the one muscle.
    """
    return [f'{name}/' for name in names] or ['']


def markdown_table() -> str:
    """docs/nodes.md's table of :data:`PARAMETERS`."""
    rows = [
        '| parameter | type | unit | default | range | per muscle | meaning |',
        '|---|---|---|---|---|---|---|',
    ]
    for p in PARAMETERS:
        default = (
            'from file'
            if p.default is None
            else f'`{p.default!r}`'.replace("'", '')
            if p.default != ''
            else '`""`'
        )
        limits = f'[{p.limits[0]:g}, {p.limits[1]:g}]' if p.limits else ''
        if p.name == 'muscle.fiber_angle':
            limits = '[0, π/2]'
        kind = p.kind + (', read-only' if p.read_only else '')
        rows.append(
            f'| `{p.name}` | {kind} | {p.unit} | {default} | {limits} | '
            f'{"yes" if p.per_muscle else ""} '
            f'| {p.description} |'
        )
    return '\n'.join(rows)
