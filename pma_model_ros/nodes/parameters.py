"""ROS parameters of every node from the core's :class:`ParameterSpec` tables.

One mechanism for the four nodes: each declares the rows of its table
(:mod:`pma_model_ros.core.files.node_parameters` and the tables it names) with :func:`declare` or
:func:`declare_table`, each with its descriptor (description, unit, range, read-only flag), and
warns about the names of its parameter files that it does not know (:func:`warn_unknown`).
``automatically_declare_parameters_from_overrides`` is not used: it would declare whatever a file
holds, without descriptors.
"""

from __future__ import annotations

import array
from dataclasses import replace
from functools import partial
from typing import Callable, Iterable, Iterator, Sequence
import weakref

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
import yaml

from .qos import PREFIX as QOS_PREFIX
from .rclpy_private import parameter_overrides
from ..core.files.node_parameters import ParameterSpec, PROCESS_PARAMETERS
from ..core.hints import did_you_mean

TYPES = {
    'double': Parameter.Type.DOUBLE,
    'integer': Parameter.Type.INTEGER,
    'string': Parameter.Type.STRING,
    'bool': Parameter.Type.BOOL,
    'double[]': Parameter.Type.DOUBLE_ARRAY,
    'string[]': Parameter.Type.STRING_ARRAY,
}
ARRAY_TYPES = (
    Parameter.Type.BYTE_ARRAY,
    Parameter.Type.BOOL_ARRAY,
    Parameter.Type.INTEGER_ARRAY,
    Parameter.Type.DOUBLE_ARRAY,
    Parameter.Type.STRING_ARRAY,
)


def descriptor(spec: ParameterSpec, description: str | None = None) -> ParameterDescriptor:
    """The ROS descriptor of ``spec``: description with unit, range, read-only flag."""
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


def declare(node: Node, spec: ParameterSpec, prefix: str = '', default: bool = True) -> Parameter:
    """Declare ``spec`` as ``prefix + spec.name`` with the value a file or ``-p`` gives, else its
    default; the parameter.  Without ``default``, or without one, a parameter nobody gives is not
    declared (a NOT_SET parameter, value None, is returned): every declared parameter has a value,
    as ``ros2 param dump`` needs (rclpy answers a GetParameters call naming an unset one with no
    values at all).  An empty sequence in a file, which rcl reads as NOT_SET, is the default.
    Already declared (a managed node configured again after a cleanup: parameters outlive it, as
    in any ROS node), it is left as it is.
    """
    name = prefix + spec.name
    if node.has_parameter(name):
        return node.get_parameter_or(name)
    given = parameter_overrides(node).get(name)
    empty = given is not None and given.type_ == Parameter.Type.NOT_SET
    if spec.kind == 'double' and given is not None and not empty:
        replace(spec, name=name).check(given.value)  # the table's words: unit, range, hint
    if not default or spec.default is None:
        if given is None or empty:
            return Parameter(name, Parameter.Type.NOT_SET)
        return node.declare_parameter(name, TYPES[spec.kind], descriptor(spec))
    if spec.default == []:
        return _declare_empty_array(node, name, spec, ignore_override=empty)
    return node.declare_parameter(name, spec.default, descriptor(spec))


#: Per node: the parameters declared by :func:`_declare_empty_array`, with their array type.
_ARRAYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _declare_empty_array(
    node: Node, name: str, spec: ParameterSpec, ignore_override: bool = False
) -> Parameter:
    """Declare ``name`` with the default ``[]`` (also over a file's ``[]``: ``ignore_override``).
    rclpy infers a parameter's type from its default and has none for ``[]`` (a byte array, to
    it): the parameter is declared with dynamic typing, and a set-parameters callback of the node
    (one, added with the first such parameter) refuses a value of any other type than the spec's
    but an empty array.
    """
    if node not in _ARRAYS:
        _ARRAYS[node] = {}
        node.add_on_set_parameters_callback(partial(_check_arrays, _ARRAYS[node]))
    _ARRAYS[node][name] = TYPES[spec.kind]
    described = descriptor(spec)
    described.dynamic_typing = True
    return node.declare_parameter(name, [], described, ignore_override=ignore_override)


def _check_arrays(
    types: dict[str, Parameter.Type], changes: list[Parameter]
) -> SetParametersResult:
    """Refuse a value of a parameter of ``types`` neither of its type nor an empty array."""
    for p in changes:
        kind = types.get(p.name)
        if kind is None or p.type_ == kind:
            continue
        if p.type_ in ARRAY_TYPES and len(p.value) == 0:
            continue
        return SetParametersResult(
            successful=False,
            reason=f"parameter '{p.name}' must be of type {kind.name}, got {p.type_.name}",
        )
    return SetParametersResult(successful=True)


def declare_table(
    node: Node, specs: Iterable[ParameterSpec], prefix: str = ''
) -> dict[str, object]:
    """Declare every row of ``specs`` under ``prefix``; their values by row name (arrays as
    lists).
    """
    return {spec.name: plain(declare(node, spec, prefix).value) for spec in specs}


def values(node: Node) -> dict[str, object]:
    """The node's set parameters as ``{dotted name: plain Python value}``."""
    return {
        name: plain(p.value)
        for name, p in node.get_parameters_by_prefix('').items()
        if p.value is not None
    }


def overrides(node: Node) -> dict[str, object]:
    """What the node's parameter files and ``-p`` set, declared or not, as ``{dotted name: plain
    value}`` (:func:`.rclpy_private.parameter_overrides`: rclpy has no public accessor).
    """
    return {name: plain(p.value) for name, p in parameter_overrides(node).items()}


def warn_unknown(node: Node, expected: Callable[[str], bool] = lambda name: False) -> list[str]:
    """Log one warning per name the node's parameter files and ``-p`` set that the node neither
    declared nor ``expected`` accepts (a file's entry it reads undeclared), with the nearest
    declared name; the warnings.  The process's parameters are known: :func:`.startup.run`
    declares ``executor`` once the node is built.  The QoS overrides (``qos_overrides.*``) are
    declared as the entities are created, after these checks: :func:`.qos.warn_unknown_overrides`
    names the unknown ones then.

    One key under several blocks (``<block>.<key>``, e.g. a node-wide key copied into each
    muscle's block) is one warning naming the blocks.  The nearest name of ``<block>.<key>`` is
    looked for among the block's names and the top-level ones only (difflib costs about 15 us a
    candidate: over every name of 64 muscles, 20 ms an unknown key, before the node answered).
    """
    declared = [*node.get_parameters_by_prefix(''), *PROCESS_PARAMETERS]
    known = set(declared)
    unknown = [
        name
        for name in sorted(overrides(node))
        if name not in known
        and not node.has_parameter(name)
        and not expected(name)
        and not name.startswith(QOS_PREFIX)
    ]
    by_block: dict[str, list[str]] = {}
    top = []
    for name in declared:
        head, dot, _ = name.partition('.')
        (by_block.setdefault(head, []) if dot else top).append(name)
    groups: dict[str, list[str]] = {}
    for name in unknown:
        head, _, key = name.partition('.')
        groups.setdefault(key if key and head in by_block else name, []).append(name)
    warnings = []
    for key, names in groups.items():
        head = names[0].partition('.')[0]
        near = did_you_mean(names[0], [*by_block[head], *top] if head in by_block else declared)
        if len(names) == 1:
            warnings.append(f"unknown parameter '{names[0]}'{near}: ignored")
        else:
            blocks = ', '.join(name.partition('.')[0] for name in names)
            warnings.append(
                f"unknown parameter '{key}' in {len(names)} blocks ({blocks}){near}: ignored"
            )
        node.get_logger().warning(warnings[-1])
    return warnings


def plain(value: object) -> object:
    """A parameter value with arrays as lists (what the core expects)."""
    return list(value) if isinstance(value, (array.array, tuple)) else value


def nest(flat: dict[str, object]) -> dict:
    """``{'a.b': 1}`` as ``{'a': {'b': 1}}`` (a parameter file's ``ros__parameters``)."""
    nested: dict = {}
    for name, value in flat.items():
        *parents, leaf = name.split('.')
        node = nested
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = value
    return nested


def check_given_types(args: Sequence[str]) -> None:
    """Raise ValueError naming a parameter that two of the command line's sources
    (``--params-file`` files, ``-p name:=value``) give one node with values of different types:
    rcl then keeps one of them without a word (``-p max_input_age:=0.5ms`` beside a file's
    ``0.1`` left the 0.1).
    """
    seen: dict[tuple[str, str], tuple[str, object, str]] = {}
    for where, node, name, value in _given(args):
        kind = _kind(value)
        first = seen.setdefault((node, name), (kind, value, where))
        if kind and first[0] and kind != first[0]:
            raise ValueError(
                f"parameter '{name}' is {first[0]} ({first[1]!r}) in {first[2]} and {kind} "
                f'({value!r}) in {where}: rcl would keep one of them without a word; give one type'
            )


def _given(args: Sequence[str]) -> Iterator[tuple[str, str, str, object]]:
    """(source, node key, dotted name, value) of every parameter the files and ``-p`` give; a
    file rcl cannot read is left to rcl's own message.
    """
    for option, text in zip(args, args[1:]):
        if option in ('-p', '--param') and ':=' in text:
            name, _, value = text.partition(':=')
            try:
                yield f'-p {text}', '/**', name, yaml.safe_load(value)
            except yaml.YAMLError:
                yield f'-p {text}', '/**', name, value
        elif option == '--params-file':
            try:
                with open(text, encoding='utf-8') as file:
                    data = yaml.safe_load(file)
            except (OSError, UnicodeDecodeError, yaml.YAMLError):
                continue
            for node, block in _blocks(data):
                for name, value in _flat(block).items():
                    yield text, node, name, value


def _blocks(data: object, path: str = '') -> Iterator[tuple[str, dict]]:
    """(node key, ``ros__parameters``) of a parameter file's (possibly namespaced) node keys."""
    if not isinstance(data, dict):
        return
    for key, value in data.items():
        if key == 'ros__parameters' and isinstance(value, dict):
            yield path, value
        else:
            yield from _blocks(value, f'{path}/{key}'.lstrip('/') if path else str(key))


def _flat(block: dict, prefix: str = '') -> dict[str, object]:
    """``{'a': {'b': 1}}`` as ``{'a.b': 1}``."""
    out: dict[str, object] = {}
    for key, value in block.items():
        if isinstance(value, dict):
            out |= _flat(value, f'{prefix}{key}.')
        else:
            out[f'{prefix}{key}'] = value
    return out


def _kind(value: object) -> str:
    """The ROS parameter type rcl reads ``value`` (PyYAML's reading) as, in words; '' for an
    empty or mixed array (rcl reads no value or refuses it itself).  A text float() reads is a
    double to rcl (``1e3``, which YAML 1.1 leaves a string).
    """
    if isinstance(value, list):
        kinds = {_kind(v) for v in value}
        return f'{kinds.pop().split()[-1]} array' if len(kinds) == 1 else ''
    if isinstance(value, bool):
        return 'a bool'
    if isinstance(value, int):
        return 'an integer'
    if isinstance(value, float):
        return 'a double'
    try:
        float(str(value))
        return 'a double'
    except ValueError:
        return 'a string'
