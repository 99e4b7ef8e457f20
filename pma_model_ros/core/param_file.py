"""Reading ROS 2 parameter files of identified muscles (``ros__parameters`` YAML).

Layout (every value SI)::

    /**:
      ros__parameters:
        muscle: {name, nominal_length, inner_diameter, membrane_thickness, fiber_angle,
        max_pressure} model: martens                 # the default model length_range: [0.198,
        0.25]    # identified length range [m] pressure_range: [0.0, 650000.0]   # identified gauge
        pressure range [Pa] (absent: up to the rated one) models:
          martens: {params: [...], objective: minimax, err: 4.2, rmse: .., r2: .., cv_err: 8.2,
                    edge_cv_err: 8.2, extrapolates: true}   # absent extrapolates: false
          # a calibrated fit (core/calibration.py) also has nominal_length [m] (replaces
          # muscle.nominal_length for this model) and pressure_offset [Pa] (the model sees gauge
          # pressure - pressure_offset)

Node settings (``ambient_pressure``, ``joint_name``, ...) may sit beside these
keys; this module reads only the muscle and its models, and
:mod:`~pma_model_ros.core.param_writer` writes them.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path

from . import calibration
from .estimation import Config
from .geometry import MuscleSpec
from .hysteresis import Follow
from .models import Domain, get_model
from .muscle_model import MuscleModel
from .node_parameters import SPECS
from .user_files import load_yaml_mapping, read_user_file

#: Node settings written into generated files, beside the muscle (documented in the README).
NODE_DEFAULTS = {
    name: SPECS[name].default
    for name in ('ambient_pressure', 'pressure_reference', 'max_input_age')
}


@dataclass(frozen=True)
class NodeSettings:
    """What the model node (and the offline tools acting as it) derive from ``ros__parameters``."""

    config: Config
    joint_name: str  #: JointState entry of the muscle
    frame_id: str  #: header.frame_id of the estimates
    hardware_id: str  #: the device: hardware_id of the muscle's diagnostic status


def read_parameters(path: str | Path) -> dict:
    """The ``ros__parameters`` mapping of a parameter file (the first node entry)."""
    data = load_yaml_mapping(read_user_file(path, 'parameter file'), str(path))
    for entry in data.values():
        if isinstance(entry, dict) and isinstance(entry.get('ros__parameters'), dict):
            return entry['ros__parameters']
    raise ValueError(f"{path}: no '<node>: ros__parameters:' mapping found")


def muscle_model(parameters: dict, model: str | None = None) -> MuscleModel:
    """Build the identified muscle from ``ros__parameters``; ``model`` overrides the default."""
    spec = MuscleSpec.from_mapping(parameters.get('muscle'))
    name = get_model(model if model is not None else parameters.get('model', '')).name
    models = parameters.get('models')
    if not isinstance(models, dict) or name not in models or not isinstance(models[name], dict):
        raise ValueError(f'models.{name} is missing from the parameter file')
    length_range = parameters.get('length_range')
    if not (isinstance(length_range, list) and len(length_range) == 2):
        raise ValueError(f'length_range must be [min, max] in m, got {length_range!r}')
    pressure_range = parameters.get('pressure_range', [0.0, math.inf])
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


def node_settings(parameters: dict, model: str | None = None) -> NodeSettings:
    """The model node's settings from ``ros__parameters`` (nested); absent node settings take their
    defaults.
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
        str(parameters.get('frame_id') or joint),
        str(parameters.get('hardware_id') or joint),
    )


def all_node_settings(parameters: dict, model: str | None = None) -> list[NodeSettings]:
    """Every muscle's settings from ``ros__parameters`` (nested): one muscle, or one per name of
    ``muscles``.

    Muscle ``<name>`` reads the block ``<name>:`` plus the node-wide settings; its joint name
    defaults to ``<name>``.  ValueError names the muscle and the problem.
    """
    names = parameters.get('muscles') or []
    if not names:
        return [node_settings(parameters, model)]
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise ValueError(f'muscles must be a list of names, got {names!r}')
    common = {key: parameters[key] for key in NODE_DEFAULTS if key in parameters}
    result = []
    for name in names:
        own = parameters.get(name)
        if not isinstance(own, dict):
            raise ValueError(f"muscle '{name}': no parameters under '{name}:'")
        try:
            result.append(
                node_settings(common | own | {'joint_name': own.get('joint_name') or name}, model)
            )
        except ValueError as err:
            raise ValueError(f"muscle '{name}': {err}") from None
    joints = [s.joint_name for s in result]
    if len(set(joints)) != len(joints):
        raise ValueError(f'two muscles share a joint_name: {joints}')
    return result
