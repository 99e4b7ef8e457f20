"""Parameters of the model node: declarations with descriptors, and their validation.

Every parameter is declared explicitly so that each carries a description,
type and range.  The nested ``models.<name>.*`` entries of a parameter file are
declared for every model this package knows (unset unless the file gives them);
entries of unknown models are ignored, as rclpy ignores any undeclared override.
``automatically_declare_parameters_from_overrides`` is not used: it would
declare the fixed parameters without descriptors.

One node serves one muscle (the parameters at the top level, as in
``config/dmsp_10_250.yaml``) or, when ``muscles`` lists names, one muscle per
name with the same parameters under ``<name>.`` (``config/example_multi_muscle.yaml``);
``ambient_pressure`` and ``max_input_age`` stay node-wide.
"""
from __future__ import annotations

import array
import math
import re

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..core.engine import PAIRINGS, STANDARD_ATMOSPHERE
from ..core.models import MODELS, get_model
from ..core.param_file import NodeSettings, all_node_settings

DOUBLE, STRING, DOUBLES = Parameter.Type.DOUBLE, Parameter.Type.STRING, Parameter.Type.DOUBLE_ARRAY
STRINGS = Parameter.Type.STRING_ARRAY

#: name: (type, description, (min, max) or None). Required: no default, must come from the file.
REQUIRED = {
    "muscle.name": (STRING, "catalogue name of the muscle, e.g. DMSP-10-250", None),
    "muscle.nominal_length": (DOUBLE, "initial (unpressurised) length L0 [m]", (0.0, 10.0)),
    "muscle.inner_diameter": (DOUBLE, "initial inner diameter D0 [m]", (0.0, 1.0)),
    "muscle.membrane_thickness": (DOUBLE, "initial membrane thickness H0 [m]", (0.0, 1.0)),
    "muscle.fiber_angle": (DOUBLE, "initial braid angle Theta0 to the muscle axis [rad]", (0.0, math.pi / 2)),
    "muscle.max_pressure": (DOUBLE, "highest rated gauge pressure [Pa]", (0.0, 5e6)),
    "model": (STRING, f"force model in use, one of models.*: {', '.join(MODELS)}", None),
    "length_range": (DOUBLES, "[min, max] length the models were identified on [m]", None),
}
#: name: (default, description, (min, max) or None); node-wide.
OPTIONAL = {
    "ambient_pressure": (STANDARD_ATMOSPHERE, "ambient pressure [Pa absolute]; gauge = fluid_pressure - ambient_pressure",
                         (0.0, 2e5)),
    "max_input_age": (0.1, "inputs whose stamp differs from the node clock by more than this are stale [s]",
                      (1e-3, 3600.0)),
}
#: name: (default, description, (min, max) or None); node-wide, fixed at start-up.
PAIRING = {
    "pairing": ("every_input", "when to estimate: every_input (each valid input, with the newest other one) or "
                "approximate_time (once per new pressure and new length whose stamps lie within pairing_slop)", None),
    "pairing_slop": (0.0005, "approximate_time: largest stamp difference of a pressure and a length paired [s]",
                     (0.0, 1.0)),
}
#: name: (default, description); per muscle (under ``<name>.`` with ``muscles``).
NAMING = {
    "joint_name": ("", "JointState entry of this muscle (empty: muscle.name; with `muscles`: the muscle's name)"),
    "frame_id": ("", "header.frame_id of force_estimate (empty: joint_name)"),
}
#: Multi-muscle parameters, fixed at start-up.
MUSCLES = "muscles"
INPUT_MODE = "input_mode"
INPUT_MODES = {"per_muscle": "topics <name>/pressure, <name>/muscle_state -> <name>/force_estimate",
               "combined": "JointStates muscle_pressures, muscle_states -> JointState force_estimates"}
_MUSCLE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
#: models.<name>.<entry>: identification results, read-only information.
MODEL_INFO = {"objective": (STRING, "identification objective"),
              "err": (DOUBLE, "max error on the map, eq. 23 [% of max force]"),
              "rmse": (DOUBLE, "root mean square error on the map [N]"),
              "r2": (DOUBLE, "coefficient of determination [-]"),
              "cv_err": (DOUBLE, "worst leave-one-length-out error [% of max force]")}


def _descriptor(description: str, limits: tuple[float, float] | None = None,
                read_only: bool = False) -> ParameterDescriptor:
    ranges = [FloatingPointRange(from_value=limits[0], to_value=limits[1])] if limits else []
    return ParameterDescriptor(description=description, floating_point_range=ranges, read_only=read_only)


def declare(node: Node) -> tuple[list[str], str]:
    """Declare every model-node parameter on ``node``; the muscle names ([] for one muscle) and input mode.

    Raises rclpy parameter exceptions on bad overrides, ValueError on a bad ``muscles`` list or mode.
    """
    names = list(node.declare_parameter(MUSCLES, STRINGS, _descriptor(
        "names of the muscles this node serves, each with its parameters under '<name>.' "
        "(unset: one muscle, parameters at the top level)", read_only=True)).value or [])
    mode = node.declare_parameter(INPUT_MODE, "per_muscle", _descriptor(
        "with `muscles`: " + "; ".join(f"{k}: {v}" for k, v in INPUT_MODES.items()), read_only=True)).value
    _check_names(names, mode)
    for name, (default, text, limits) in OPTIONAL.items():
        node.declare_parameter(name, default, _descriptor(text, limits))
    for name, (default, text, limits) in PAIRING.items():
        node.declare_parameter(name, default, _descriptor(text, limits, read_only=True))
    for prefix in [f"{name}." for name in names] or [""]:
        _declare_muscle(node, prefix)
    return names, mode


def _declare_muscle(node: Node, prefix: str) -> None:
    for name, (kind, text, limits) in REQUIRED.items():
        node.declare_parameter(prefix + name, kind, _descriptor(text, limits))
    for name, (default, text) in NAMING.items():
        node.declare_parameter(prefix + name, default, _descriptor(text))
    for model in MODELS.values():
        node.declare_parameter(f"{prefix}models.{model.name}.params", DOUBLES, _descriptor(
            f"identified parameters {list(model.param_names)} of {model.name} ({model.equation}), SI units"))
        for entry, (kind, text) in MODEL_INFO.items():
            node.declare_parameter(f"{prefix}models.{model.name}.{entry}", kind, _descriptor(text, read_only=True))


def _check_names(names: list[str], mode: str) -> None:
    if mode not in INPUT_MODES:
        raise ValueError(f"parameter '{INPUT_MODE}': unknown mode {mode!r}; one of {', '.join(INPUT_MODES)}")
    bad = [n for n in names if not _MUSCLE_NAME.fullmatch(n)]
    if bad:
        raise ValueError(f"parameter '{MUSCLES}': {bad[0]!r} is not a name (letters, digits, '_'; a letter first)")
    if len(set(names)) != len(names):
        raise ValueError(f"parameter '{MUSCLES}': duplicate names in {names}")


def pairing(flat: dict[str, object]) -> dict[str, object]:
    """The engine's pairing arguments from the node's parameters; ValueError names a bad one."""
    rule = flat.get("pairing", PAIRING["pairing"][0])
    if rule not in PAIRINGS:
        raise ValueError(f"parameter 'pairing': unknown rule {rule!r}; one of {', '.join(PAIRINGS)}")
    return {"pairing": rule, "slop": float(flat.get("pairing_slop", PAIRING["pairing_slop"][0]))}


def values(node: Node) -> dict[str, object]:
    """The node's set parameters as ``{dotted name: plain Python value}``."""
    return {name: plain(p.value) for name, p in node.get_parameters_by_prefix("").items() if p.value is not None}


def all_settings(flat: dict[str, object], names: list[str]) -> list[NodeSettings]:
    """Settings of every muscle of a would-be parameter set (one without ``names``; see
    :func:`~pma_model_ros.core.param_file.all_node_settings`).  ValueError names the muscle and parameter."""
    for prefix in [f"{name}." for name in names] or [""]:
        where = f"muscle '{prefix[:-1]}': " if prefix else ""
        missing = [name for name in REQUIRED if prefix + name not in flat]
        if missing:
            raise ValueError(f"{where}parameter '{missing[0]}' is not set (missing from the parameter file?)")
        try:
            get_model(flat[prefix + "model"])
        except ValueError as err:
            raise ValueError(f"{where}parameter 'model': {err}") from None
    return all_node_settings(_nest(flat))


def plain(value: object) -> object:
    """A parameter value with arrays as lists (what the core expects)."""
    return list(value) if isinstance(value, (array.array, tuple)) else value


def _nest(flat: dict[str, object]) -> dict:
    nested: dict = {}
    for name, value in flat.items():
        *parents, leaf = name.split(".")
        node = nested
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = value
    return nested
