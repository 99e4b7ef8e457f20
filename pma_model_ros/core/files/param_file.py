"""Reading ROS 2 parameter files of identified muscles (``ros__parameters`` YAML).

Layout (every value SI; ``config/dmsp_10_250.yaml``, its martens entry)::

    /**:
      ros__parameters:
        muscle: {name: DMSP-10-250, nominal_length: 0.25, inner_diameter: 0.01,
                 membrane_thickness: 0.0018, fiber_angle: 0.49916416607, max_pressure: 800000.0}
        # a file of pma-model fit also has muscle.given_nominal_length [m]: the L0 of the spec
        # as given (measured), where nominal_length is the calibrated one; a record for
        # pma-model scale, not a ROS parameter
        model: martens                   # the default model
        length_range: [0.198, 0.25]      # identified length range [m]
        pressure_range: [0.0, 650000.0]  # identified gauge pressure range [Pa] (absent: rated)
        models:
          martens:
            params: [121624751.807, -1339251496.3, 4799295897.81, -5346910897.11,
                     -0.0990271864564]
            extrapolates: true           # absent: false
            # identification results (diagnostics values, not ROS parameters):
            objective: minimax
            err: 4.20302723951
            rmse: 7.92133215146
            r2: 0.996811298801
            cv_err: 8.81150464667        # the worst nested held-out err [%]
            interior_cv_err: 4.65750678692  # ... between the shortest and longest length
            edge_cv_err: 8.81150464667   # ... at those two (the served extrapolation's)
            held_out:                    # nested held-out err [%] of each identified length
              lengths: [0.25, 0.234, 0.219, 0.204, 0.198]
              err: [8.81150464667, 4.65750678692, 1.79429019697, 0.406203929704, 0.44477631869]
              max_force: 542.5
            # a calibrated fit (core/identification/calibration.py) also has nominal_length [m]
            # (replaces muscle.nominal_length for this model) and pressure_offset [Pa] (the model
            # sees gauge pressure - pressure_offset)

Node settings (``ambient_pressure``, ``joint_name``, ...) may sit beside these
keys; this module reads only the muscle and its models, and
:mod:`~pma_model_ros.core.files.param_writer` writes them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from pathlib import Path
from typing import Sequence

from .joint_node_parameters import (
    JOINT_MUSCLE_PARAMETERS,
    JOINT_NODE_PARAMETERS,
    JOINT_PARAMETERS,
)
from .node_parameters import (
    frame_of,
    IDENTIFICATION,
    MODEL_BLOCK,
    names_of,
    PARAMETERS,
    PROCESS_PARAMETERS,
    SPECS,
)
from .user_files import load_yaml_mapping, read_user_file
from ..hints import did_you_mean, missing_key, unknown_keys
from ..identification import calibration
from ..identification.validation import HeldOutBand
from ..physics.geometry import MuscleSpec
from ..physics.hysteresis import Follow
from ..physics.models import ALIASES, Domain, get_model, MODELS
from ..physics.muscle_model import MuscleModel
from ..runtime.engine import Engine
from ..runtime.estimation import Config
from ..runtime.health import node_timing, Status

#: Node settings written into generated files, beside the muscle (documented in docs/nodes.md).
NODE_DEFAULTS = {
    name: SPECS[name].default
    for name in ('ambient_pressure', 'pressure_reference', 'max_input_age')
}


#: Key of ``muscle`` holding the given (measured) rest length [m] beside a calibrated
#: ``nominal_length`` (module doc); not part of the spec the models use.
GIVEN_LENGTH = 'given_nominal_length'


def spec_mapping(muscle: object) -> object:
    """The muscle spec keys of a file's ``muscle`` mapping: without :data:`GIVEN_LENGTH`."""
    if isinstance(muscle, dict):
        return {k: v for k, v in muscle.items() if k != GIVEN_LENGTH}
    return muscle


#: Parameters rclpy gives every node; a file may set them.
ROS_PARAMETERS = ('use_sim_time', 'qos_overrides', 'start_type_description_service')
#: Keys of a file's top level that model_node reads (with ``muscles:``: beside their blocks).
NODE_KEYS = (*dict.fromkeys(s.name.split('.')[0] for s in PARAMETERS if not s.per_muscle),)
#: Keys of one muscle: a single-muscle file's top level, or a block of a ``muscles:`` file.
MUSCLE_KEYS = (*dict.fromkeys(s.name.split('.')[0] for s in PARAMETERS if s.per_muscle),)
#: Keys of one entry of ``models:`` and of ``hysteresis:``.
MODEL_ENTRY_KEYS = MODEL_BLOCK + IDENTIFICATION
HYSTERESIS_KEYS = tuple(
    s.name.removeprefix('hysteresis.') for s in PARAMETERS if s.name.startswith('hysteresis.')
)


@dataclass(frozen=True)
class NodeSettings:
    """What the model node (and the offline tools acting as it) derive from ``ros__parameters``."""

    config: Config
    joint_name: str  #: JointState entry of the muscle
    frame_id: str  #: header.frame_id of the estimates
    hardware_id: str  #: the device: hardware_id of the muscle's diagnostic status
    #: the model's identification results, as diagnostic key-values (:func:`identification`)
    identification: dict[str, str]
    #: the model's nested held-out error per identified length (None: the file has none)
    band: HeldOutBand | None

    def status_values(self, length: float) -> dict[str, str]:
        """What the muscle's /diagnostics status adds to the engine's values: the identification
        results and the expected error at ``length`` [m], its newest valid length (NaN: none).
        """
        if self.band is None:
            return self.identification
        return self.identification | self.band.values_at(length)

    def status_entry(self, status: Status, length: float) -> tuple[str, str, int, str, dict]:
        """The muscle's /diagnostics entry (name, hardware_id, level, message, values) of the
        engine's ``status``, with :meth:`status_values` at ``length`` [m] (model_node and
        ``bag estimate`` alike; :func:`~pma_model_ros.wire.diagnostics.diagnostic_array`).
        """
        return (
            self.joint_name,
            self.hardware_id,
            int(status.level),
            status.message,
            status.values | self.status_values(length),
        )


def read_parameters(path: str | Path) -> dict:
    """The ``ros__parameters`` mapping of a parameter file (the first node entry).

    ValueError names each key no node of this package reads, with the known key it looks like
    (:func:`unknown_parameters`): a typo would otherwise be silently ignored.
    """
    data = load_yaml_mapping(read_user_file(path, 'parameter file'), str(path))
    for entry in data.values():
        if isinstance(entry, dict) and isinstance(entry.get('ros__parameters'), dict):
            parameters = entry['ros__parameters']
            problems = unknown_parameters(parameters)
            if problems:
                raise ValueError(f'{path}: ' + '; '.join(problems))
            return parameters
    refuse_muscle_spec(data, path)
    raise ValueError(f"{path}: no '<node>: ros__parameters:' mapping found")


def refuse_muscle_spec(data: dict, path: str | Path) -> None:
    """Refuse (ValueError) ``data``, the top mapping of the file ``path``, if it is a muscle spec
    (its keys or ``muscle:``, no ``ros__parameters``) where a ROS parameter file is wanted.
    """
    nodes = [v for v in data.values() if isinstance(v, dict) and 'ros__parameters' in v]
    if not nodes and set(data) <= set(MuscleSpec.__dataclass_fields__) | {'muscle'}:
        raise ValueError(
            f'{path} is a muscle spec, not a ROS parameter file '
            f"('<node>: ros__parameters:'); make one with pma-model fit --muscle {path}"
        )


def check_params_file(path: str | Path) -> None:
    """A node's ``--params-file`` before rcl reads it: ValueError if it is a muscle spec (rcl says
    only 'Cannot have a value before ros__parameters'); rcl reports any other problem itself.
    """
    try:
        data = load_yaml_mapping(read_user_file(path, 'parameter file'), str(path))
    except ValueError:
        return
    refuse_muscle_spec(data, path)


def unknown_parameters(parameters: dict) -> list[str]:
    """One message per key of ``ros__parameters`` (nested) that no node of this package reads,
    naming the known key it looks like: single- or multi-muscle files (model_node), joint files
    (``joints:``, joint_node).
    """
    if 'joints' in parameters:
        return unknown_joint_parameters(parameters)
    names = parameters.get('muscles') or []
    names = [n for n in names if isinstance(n, str)] if isinstance(names, list) else []
    if not names:
        return unknown_muscle_parameters(parameters, (*NODE_KEYS, *ROS_PARAMETERS))
    problems = unknown_keys(parameters, (*NODE_KEYS, *ROS_PARAMETERS, *names))
    for name in names:
        if isinstance(parameters.get(name), dict):
            problems += unknown_muscle_parameters(parameters[name], (), f'{name}.')
    return problems


def unknown_muscle_parameters(block: dict, others: tuple[str, ...], where: str = '') -> list[str]:
    """:func:`unknown_parameters` of one muscle's keys (``others``: also allowed beside them)."""
    problems = unknown_keys(block, (*MUSCLE_KEYS, *others), where)
    models = block.get('models')
    if isinstance(models, dict):
        problems += unknown_keys(models, (*MODELS, *ALIASES), f'{where}models.')
        for name, entry in models.items():
            if isinstance(entry, dict):
                problems += unknown_keys(entry, MODEL_ENTRY_KEYS, f'{where}models.{name}.')
    if isinstance(block.get('hysteresis'), dict):
        problems += unknown_keys(block['hysteresis'], HYSTERESIS_KEYS, f'{where}hysteresis.')
    return problems


def unknown_joint_parameters(parameters: dict) -> list[str]:
    """One message per key of a joint file's ``ros__parameters`` that joint_node does not read,
    naming the known key it looks like (a muscle given by ``file`` is checked when it is read).
    """
    names = parameters.get('joints')
    names = [n for n in names if isinstance(n, str)] if isinstance(names, list) else []
    every_node = (*PROCESS_PARAMETERS, *ROS_PARAMETERS)
    problems = unknown_keys(parameters, (*names_of(JOINT_NODE_PARAMETERS), *every_node, *names))
    for name in names:
        block = parameters.get(name)
        if not isinstance(block, dict):
            continue
        muscles = block.get('muscles')
        muscles = [m for m in muscles if isinstance(m, str)] if isinstance(muscles, list) else []
        problems += unknown_keys(block, (*names_of(JOINT_PARAMETERS), *muscles), f'{name}.')
        for muscle in muscles:
            if isinstance(block.get(muscle), dict):
                problems += unknown_muscle_parameters(
                    block[muscle], names_of(JOINT_MUSCLE_PARAMETERS), f'{name}.{muscle}.'
                )
    return problems


def muscle_model(parameters: dict, model: str | None = None) -> MuscleModel:
    """Build the identified muscle from ``ros__parameters``; ``model`` overrides the default."""
    for key in ('muscle', 'length_range', 'models', *(('model',) if model is None else ())):
        if key not in parameters:
            raise ValueError(missing_key(key, parameters, MUSCLE_KEYS))
    spec = MuscleSpec.from_mapping(spec_mapping(parameters['muscle']))
    name = get_model(model if model is not None else parameters['model']).name
    models = parameters['models']
    if not isinstance(models, dict) or not isinstance(models.get(name), dict):
        raise ValueError(
            missing_key(name, models if isinstance(models, dict) else {}, MODELS, 'models.')
            + (
                ' from the parameter file'
                if isinstance(models, dict)
                else ': models must be a mapping'
            )
        )
    length_range = parameters.get('length_range')
    if not (isinstance(length_range, list) and len(length_range) == 2):
        raise ValueError(f'length_range must be [min, max] in m, got {length_range!r}')
    pressure_range = parameters.get('pressure_range', [])
    if isinstance(pressure_range, list) and not pressure_range:  # absent or empty: up to rated
        pressure_range = [0.0, math.inf]
    if not (
        isinstance(pressure_range, list) and len(pressure_range) == 2 and pressure_range[0] == 0
    ):
        raise ValueError(f'pressure_range must be [0, max] in Pa gauge, got {pressure_range!r}')
    extrapolates = models[name].get('extrapolates', False)
    if not isinstance(extrapolates, bool):
        raise ValueError(f'models.{name}.extrapolates must be true or false, got {extrapolates!r}')
    try:
        domain = Domain(*(float(v) for v in length_range), float(pressure_range[1]), extrapolates)
    except (TypeError, ValueError, OverflowError) as err:
        raise ValueError(f'length_range/pressure_range: {err}') from None
    entry, model = models[name], get_model(name)
    params = entry.get('params', [])
    if 'nominal_length' in entry:
        spec = MuscleSpec.from_mapping(
            spec.to_mapping() | {'nominal_length': entry['nominal_length']}
        )
    if 'pressure_offset' in entry:
        offset = entry['pressure_offset']
        if (
            isinstance(offset, bool)
            or not isinstance(offset, (int, float))
            or not abs(offset) <= calibration.PRESSURE_BOUND
        ):
            raise ValueError(
                f'models.{name}.pressure_offset must be a number in '
                f'[-{calibration.PRESSURE_BOUND:g}, {calibration.PRESSURE_BOUND:g}] Pa, got '
                f'{offset!r}'
            )
        model, params = (
            calibration.shifted(model),
            [*params, offset] if isinstance(params, list) else params,
        )
    return MuscleModel(spec, model, params, domain)


def file_kind(parameters: dict) -> str:
    """What a parameter file is, from its ``ros__parameters``: ``'joint'`` (``joints:``, read by
    joint_node and ``pma-model joint``), ``'muscles'`` (several muscles, ``muscles:``) or
    ``'muscle'`` (one muscle).
    """
    if 'joints' in parameters:
        return 'joint'
    return 'muscles' if parameters.get('muscles') else 'muscle'


def muscle_parameters(parameters: dict, name: str) -> dict:
    """Muscle ``name``'s parameters of a ``muscles:`` file: its block ``<name>:`` over the
    node-wide settings, its joint name defaulting to ``name``.
    """
    own = parameters.get(name)
    if not isinstance(own, dict):
        raise ValueError(f"no parameters under '{name}:'")
    common = {key: parameters[key] for key in NODE_DEFAULTS if key in parameters}
    return common | own | {'joint_name': own.get('joint_name') or name}


def one_muscle(parameters: dict, muscle: str | None = None) -> dict:
    """The parameters of one muscle of a file's ``ros__parameters``: those of a one-muscle file,
    or of the muscle named ``muscle`` of a ``muscles:`` file; ValueError saying what the file is
    and what to pass instead (a joint file, a muscles: file without ``muscle``).
    """
    kind = file_kind(parameters)
    if kind == 'joint':
        raise _joint_file(parameters)
    if kind == 'muscle':
        if muscle is not None:
            raise ValueError(f"--muscle {muscle}: a file of one muscle, not of 'muscles:'")
        return parameters
    names = parameters['muscles']
    if muscle is None:
        raise ValueError(
            f'a file of several muscles (muscles: {names}), read whole by model_node and bag '
            "estimate; pass one muscle's parameter file (force and pressure pick one of these "
            'with --muscle NAME)'
        )
    if muscle not in names:
        raise ValueError(f"no muscle '{muscle}'{did_you_mean(muscle, names)} in muscles: {names}")
    try:
        return muscle_parameters(parameters, muscle)
    except ValueError as err:
        raise ValueError(f"muscle '{muscle}': {err}") from None


def _joint_file(parameters: dict) -> ValueError:
    """The error of a joint file where a muscle's parameter file is wanted, with its muscles'
    files.
    """
    return ValueError(
        f'a joint file (joints: {parameters["joints"]}), read by pma-model joint and joint_node; '
        "pass one muscle's parameter file" + _muscle_files(parameters)
    )


def _muscle_files(parameters: dict) -> str:
    """`` (its muscles' files: a.yaml, b.yaml)`` of a joint file's muscles given by ``file``."""
    files = [
        str(block[m]['file'])
        for j in parameters.get('joints') or []
        if isinstance(block := parameters.get(j), dict)
        for m in block.get('muscles') or []
        if isinstance(block.get(m), dict) and block[m].get('file')
    ]
    return f" (its muscles' files, beside it: {', '.join(dict.fromkeys(files))})" if files else ''


def load_muscle(
    path: str | Path, model: str | None = None, parameters: dict | None = None
) -> MuscleModel:
    """:func:`muscle_model` of the parameter file ``path`` (``parameters``: its
    :func:`read_parameters`, if read already); errors of the file name it, and a file of
    another kind (:func:`one_muscle`) says what it is.
    """
    if model is not None:
        get_model(model)  # an unknown override is the caller's, not the file's
    parameters = read_parameters(path) if parameters is None else parameters
    try:
        return muscle_model(one_muscle(parameters), model)
    except ValueError as err:
        raise ValueError(f'{path}: {err}') from None


def held_out_band(parameters: dict, model: str | None = None) -> HeldOutBand | None:
    """The nested held-out error per identified length of the model (``models.<name>.held_out``,
    written by ``pma-model fit`` and ``make-config``); None where the file has none.
    """
    name = get_model(model if model is not None else parameters.get('model', '')).name
    entry = (parameters.get('models') or {}).get(name) or {}
    held = entry.get('held_out')
    if held is None:
        return None
    try:
        return HeldOutBand(
            tuple(float(v) for v in held['lengths']),
            tuple(float(v) for v in held['err']),
            float(held['max_force']),
        )
    except (KeyError, TypeError, ValueError) as err:
        raise ValueError(
            f'models.{name}.held_out must map lengths [m], err [%] and max_force [N]: {err}'
        ) from None


#: The unit of each identification result (:data:`~.node_parameters.IDENTIFICATION`).
IDENTIFICATION_UNITS = {
    'objective': '',
    'err': '% of max force',
    'rmse': 'N',
    'r2': '',
    'cv_err': '% of max force',
    'interior_cv_err': '% of max force',
    'edge_cv_err': '% of max force',
}


def identification(parameters: dict, model: str | None = None) -> dict[str, str]:
    """The identification results of the muscle's model (``model`` overrides the default) from
    its ``ros__parameters`` (nested), as diagnostic key-values ``identification <entry> [unit]``
    (the held-out error of each identified length as ``identification held_out [m: % of max
    force]``); entries the file lacks are left out.
    """
    name = get_model(model if model is not None else parameters.get('model', '')).name
    models = parameters.get('models')
    entry = models.get(name) if isinstance(models, dict) else None
    values = {}
    for key in IDENTIFICATION_UNITS:
        value = entry.get(key) if isinstance(entry, dict) else None
        if value is not None:
            unit = IDENTIFICATION_UNITS[key]
            text = f'{value:.6g}' if isinstance(value, float) else str(value)
            values[f'identification {key}' + (f' [{unit}]' if unit else '')] = text
    band = held_out_band(parameters, model)
    if band is not None:
        values['identification held_out [m: % of max force]'] = ', '.join(
            f'{length:.4g}: {err:.3g}' for length, err in zip(band.lengths, band.errors)
        )
    return values


def hysteresis_follow(parameters: dict) -> Follow:
    """What the muscle's hysteresis branch follows, from the ``hysteresis`` mapping of its
    ``ros__parameters`` (nested; absent entries take the parameter table's defaults).
    """
    hysteresis = parameters.get('hysteresis') or {}
    if not isinstance(hysteresis, dict):
        raise ValueError(
            f'hysteresis must be a mapping (input, length_deadband, pressure_deadband), got '
            f'{hysteresis!r}'
        )
    follow = hysteresis.get('input', SPECS['hysteresis.input'].default)
    SPECS['hysteresis.input'].check(follow)
    deadband = SPECS[f'hysteresis.{follow}_deadband']
    value = hysteresis.get(f'{follow}_deadband')
    return Follow(follow, deadband.check(deadband.default if value is None else value))


def node_pairing(parameters: dict) -> dict[str, object]:
    """The engine's pairing arguments (``pairing``, ``slop`` [s]) from a node's parameters (a
    parameter file's, or the node's own): node-wide, as model_node reads them.
    """
    return {
        'pairing': parameters.get('pairing', SPECS['pairing'].default),
        'slop': parameters.get('pairing_slop', SPECS['pairing_slop'].default),
    }


def node_engine(
    settings: Sequence[NodeSettings],
    pairing: str = SPECS['pairing'].default,
    slop: float = SPECS['pairing_slop'].default,
    max_answer_delay: float = SPECS['max_answer_delay'].default,
) -> Engine:
    """The engine model_node runs for ``settings`` (one per muscle): their configs, the node's
    report timing (:func:`~pma_model_ros.core.runtime.health.node_timing`), its ``pairing``
    (``slop`` [s]) and ``max_answer_delay`` [s].
    """
    return Engine(
        [s.config for s in settings],
        **node_timing(len(settings)),
        pairing=pairing,
        slop=slop,
        max_answer_delay=max_answer_delay,
    )


def node_settings(parameters: dict, model: str | None = None, instance: str = '') -> NodeSettings:
    """The model node's settings from ``ros__parameters`` (nested); absent node settings take their
    defaults.  ``instance``: the node's fully qualified name; an unset ``hardware_id`` is then
    ``<instance>/<joint_name>``, unique per node (without: '', until :func:`in_node` names it).
    """
    muscle = muscle_model(parameters, model)
    values = NODE_DEFAULTS | {k: parameters[k] for k in NODE_DEFAULTS if k in parameters}
    try:
        ambient, max_age = float(values['ambient_pressure']), float(values['max_input_age'])
    except (TypeError, ValueError, OverflowError) as err:
        raise ValueError(f'ambient_pressure/max_input_age must be numbers: {err}') from None
    follow = hysteresis_follow(parameters)
    config = Config(muscle, ambient, max_age, values['pressure_reference'], follow)
    joint = str(parameters.get('joint_name') or muscle.spec.name)
    return NodeSettings(
        config,
        joint,
        str(parameters.get('frame_id') or frame_of(joint)),
        str(parameters.get('hardware_id') or (f'{instance}/{joint}' if instance else '')),
        identification(parameters, model),
        held_out_band(parameters, model),
    )


def in_node(settings: Sequence[NodeSettings], instance: str) -> list[NodeSettings]:
    """``settings`` (made without an ``instance``) as the node of fully qualified name
    ``instance`` has them: an unset ``hardware_id`` is ``<instance>/<joint_name>``.
    """
    return [
        s if s.hardware_id else replace(s, hardware_id=f'{instance}/{s.joint_name}')
        for s in settings
    ]


def all_node_settings(
    parameters: dict, model: str | None = None, instance: str = ''
) -> list[NodeSettings]:
    """Every muscle's settings from ``ros__parameters`` (nested): one muscle, or one per name of
    ``muscles`` (``instance``: as :func:`node_settings`'s).

    Muscle ``<name>`` reads the block ``<name>:`` plus the node-wide settings; its joint name
    defaults to ``<name>``.  ValueError names the muscle and the problem.
    """
    names = parameters.get('muscles') or []
    if file_kind(parameters) == 'joint':
        raise _joint_file(parameters)
    if not names:
        return [node_settings(parameters, model, instance)]
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise ValueError(f'muscles must be a list of names, got {names!r}')
    result = []
    for name in names:
        try:
            result.append(node_settings(muscle_parameters(parameters, name), model, instance))
        except ValueError as err:
            raise ValueError(f"muscle '{name}': {err}") from None
    joints = [s.joint_name for s in result]
    if len(set(joints)) != len(joints):
        raise ValueError(f'two muscles share a joint_name: {joints}')
    return result
