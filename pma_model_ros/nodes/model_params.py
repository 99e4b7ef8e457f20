"""Parameters of the model node: ROS declarations of :mod:`pma_model_ros.core.node_parameters`, and
validation.

Every parameter is declared explicitly from that table, so that each carries its description,
unit, range and read-only flag.  The nested ``models.<name>.*`` entries of a parameter file are
declared for every model this package knows (unset unless the file gives them); entries of unknown
models are ignored, as rclpy ignores any undeclared override.
``automatically_declare_parameters_from_overrides`` is not used: it would declare the fixed
parameters without descriptors.

One node serves one muscle (the per-muscle parameters at the top level, as in
``config/dmsp_10_250.yaml``) or, when ``muscles`` lists names, one muscle per name with the
per-muscle parameters under ``<name>.`` (``config/example_multi_muscle.yaml``); the others are
node-wide.  ``executor`` is declared by :mod:`pma_model_ros.nodes.startup`.
"""

from __future__ import annotations

import array
import re

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..core.models import get_model, MODELS
from ..core.node_parameters import PARAMETERS, ParameterSpec, SPECS
from ..core.param_file import all_node_settings, NodeSettings

TYPES = {
    'double': Parameter.Type.DOUBLE,
    'string': Parameter.Type.STRING,
    'bool': Parameter.Type.BOOL,
    'double[]': Parameter.Type.DOUBLE_ARRAY,
    'string[]': Parameter.Type.STRING_ARRAY,
}
#: Parameters required per muscle (no default: from the file), without the models.* entries.
REQUIRED = [p.name for p in PARAMETERS if p.default is None and not p.name.startswith('models.')]
_MUSCLE_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
#: models.<name>.<entry>: identification results, read-only information (see the table's models.*
#: row).
MODEL_INFO = {
    'objective': Parameter.Type.STRING,
    'err': Parameter.Type.DOUBLE,
    'rmse': Parameter.Type.DOUBLE,
    'r2': Parameter.Type.DOUBLE,
    'cv_err': Parameter.Type.DOUBLE,
    'edge_cv_err': Parameter.Type.DOUBLE,
    'held_out.lengths': Parameter.Type.DOUBLE_ARRAY,
    'held_out.err': Parameter.Type.DOUBLE_ARRAY,
    'held_out.max_force': Parameter.Type.DOUBLE,
}


def descriptor(spec: ParameterSpec, description: str | None = None) -> ParameterDescriptor:
    """The ROS descriptor of ``spec``: description with unit and choices, range, read-only flag."""
    text = description or spec.description
    if spec.unit:
        text += f' [{spec.unit}]'
    ranges = (
        [FloatingPointRange(from_value=spec.limits[0], to_value=spec.limits[1])]
        if spec.limits
        else []
    )
    return ParameterDescriptor(
        description=text, floating_point_range=ranges, read_only=spec.read_only
    )


def _declare(node: Node, spec: ParameterSpec, name: str | None = None, default: bool = True):
    # no value: the type alone
    value = spec.default if default and spec.default not in (None, []) else TYPES[spec.kind]
    return node.declare_parameter(name or spec.name, value, descriptor(spec))


def declare(node: Node) -> tuple[list[str], str]:
    """Declare every model-node parameter on ``node``; the muscle names ([] for one muscle) and
    input mode.

    Raises rclpy parameter exceptions on bad overrides, ValueError on a bad ``muscles`` list or
    mode.
    """
    names = list(_declare(node, SPECS['muscles']).value or [])
    mode = _declare(node, SPECS['input_mode']).value
    _check_names(names, mode)
    for spec in PARAMETERS:
        if not spec.per_muscle and spec.name not in ('muscles', 'input_mode', 'executor'):
            _declare(node, spec)
    for prefix in [f'{name}.' for name in names] or ['']:
        declare_muscle(node, prefix)
    return names, mode


def declare_muscle(node: Node, prefix: str, defaults: bool = True) -> None:
    """Declare one muscle's parameters under ``prefix``; without ``defaults`` unset ones stay
    unset (joint_node: a muscle ``file``'s values then apply).
    """
    for spec in PARAMETERS:
        if spec.per_muscle and not spec.name.startswith('models.'):
            _declare(node, spec, prefix + spec.name, defaults)
    params, info = (
        SPECS['models.<model>.params'],
        SPECS['models.<model>.{objective, err, rmse, r2, cv_err, edge_cv_err, held_out}'],
    )
    extrapolates = SPECS['models.<model>.extrapolates']
    for model in MODELS.values():
        node.declare_parameter(
            f'{prefix}models.{model.name}.params',
            TYPES['double[]'],
            descriptor(
                params,
                f'identified parameters {list(model.param_names)} of {model.name} '
                f'({model.equation}), SI units',
            ),
        )
        node.declare_parameter(
            f'{prefix}models.{model.name}.extrapolates', TYPES['bool'], descriptor(extrapolates)
        )
        for entry, kind in MODEL_INFO.items():
            node.declare_parameter(f'{prefix}models.{model.name}.{entry}', kind, descriptor(info))
        for entry in ('nominal_length', 'pressure_offset'):
            node.declare_parameter(
                f'{prefix}models.{model.name}.{entry}',
                Parameter.Type.DOUBLE,
                descriptor(SPECS['models.<model>.{nominal_length, pressure_offset}']),
            )


def _check_names(names: list[str], mode: str) -> None:
    SPECS['input_mode'].check(mode)
    bad = [n for n in names if not _MUSCLE_NAME.fullmatch(n)]
    if bad:
        raise ValueError(
            f"parameter 'muscles': {bad[0]!r} is not a name (letters, digits, '_'; a letter first)"
        )
    if len(set(names)) != len(names):
        raise ValueError(f"parameter 'muscles': duplicate names in {names}")


def pairing(flat: dict[str, object]) -> dict[str, object]:
    """The engine's pairing arguments from the node's parameters."""
    return {
        'pairing': flat.get('pairing', SPECS['pairing'].default),
        'slop': flat.get('pairing_slop', SPECS['pairing_slop'].default),
    }


def values(node: Node) -> dict[str, object]:
    """The node's set parameters as ``{dotted name: plain Python value}``."""
    return {
        name: plain(p.value)
        for name, p in node.get_parameters_by_prefix('').items()
        if p.value is not None
    }


def all_settings(flat: dict[str, object], names: list[str]) -> list[NodeSettings]:
    """Settings of every muscle of a would-be parameter set (one without ``names``; see
    :func:`~pma_model_ros.core.param_file.all_node_settings`).  ValueError names the muscle and
    parameter.
    """
    for prefix in [f'{name}.' for name in names] or ['']:
        where = f"muscle '{prefix[:-1]}': " if prefix else ''
        missing = [name for name in REQUIRED if prefix + name not in flat]
        if missing:
            raise ValueError(
                f"{where}parameter '{missing[0]}' is not set (missing from the parameter file?)"
            )
        try:
            get_model(flat[prefix + 'model'])
        except ValueError as err:
            raise ValueError(f"{where}parameter 'model': {err}") from None
    return all_node_settings(nest(flat))


def plain(value: object) -> object:
    """A parameter value with arrays as lists (what the core expects)."""
    return list(value) if isinstance(value, (array.array, tuple)) else value


def nest(flat: dict[str, object]) -> dict:
    nested: dict = {}
    for name, value in flat.items():
        *parents, leaf = name.split('.')
        node = nested
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = value
    return nested
