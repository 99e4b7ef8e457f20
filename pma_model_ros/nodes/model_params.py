"""Parameters of the model node: ROS declarations of
:mod:`pma_model_ros.core.files.node_parameters`, the model blocks, and validation.

One node serves one muscle (the per-muscle parameters at the top level, as in
``config/dmsp_10_250.yaml``) or, when ``muscles`` lists names, one muscle per name with the
per-muscle parameters under ``<name>.`` (``config/example_multi_muscle.yaml``); the others are
node-wide.  ``executor`` and ``autostart`` are declared by
:mod:`pma_model_ros.nodes.managed`.

Of a muscle's ``models.<model>.*`` entries only the selected ``model``'s block
(:data:`~pma_model_ros.core.files.node_parameters.MODEL_BLOCK`) is declared; the other models'
blocks and every identification result stay where the file put them (:class:`ModelBlocks`), so that
switching ``model`` at runtime declares the new model's block and a whole parameter file still
loads atomically.
"""

from __future__ import annotations

from dataclasses import replace
import re

from rclpy.node import Node
from rclpy.parameter import Parameter

from .parameters import declare as declare_spec
from .parameters import descriptor, nest, overrides, plain, TYPES, values
from ..core.files.node_parameters import (
    IDENTIFICATION,
    MODEL_BLOCK,
    PARAMETERS,
    PROCESS_PARAMETERS,
    SPECS,
)
from ..core.files.param_file import (
    all_node_settings,
    file_kind,
    GIVEN_LENGTH,
    NodeSettings,
    one_muscle,
)
from ..core.physics.models import ALIASES, get_model, MODELS

#: Parameters required per muscle (no default: from the file), without the models.* entries.
REQUIRED = [p.name for p in PARAMETERS if p.default is None and not p.name.startswith('models.')]
_MUSCLE_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
#: The table row of each entry of a model's block.
BLOCK_SPECS = {
    'params': SPECS['models.<model>.params'],
    'extrapolates': SPECS['models.<model>.extrapolates'],
    'nominal_length': SPECS['models.<model>.{nominal_length, pressure_offset}'],
    'pressure_offset': SPECS['models.<model>.{nominal_length, pressure_offset}'],
}
#: ``<prefix>models.<model>.<entry>`` of any known model and entry (block or identification).
_MODEL_ENTRY = re.compile(
    rf'(.*)models\.({"|".join(MODELS)})\.({"|".join(MODEL_BLOCK + IDENTIFICATION)})(\..+)?'
)


def declare(node: Node) -> tuple[list[str], str]:
    """Declare every model-node parameter on ``node``; the muscle names ([] for one muscle) and
    input mode.

    Raises rclpy parameter exceptions on bad overrides, ValueError on a bad ``muscles`` list or
    mode.
    """
    given = nest(overrides(node))
    if file_kind(given) == 'joint':
        one_muscle(given)  # raises: a joint file, read by joint_node, and its muscles' files
    names = list(declare_spec(node, SPECS['muscles']).value or [])
    mode = declare_spec(node, SPECS['input_mode']).value
    _check_names(names, mode)
    for spec in PARAMETERS:
        if not spec.per_muscle and spec.name not in (
            'muscles',
            'input_mode',
            *PROCESS_PARAMETERS,
        ):
            declare_spec(node, spec)
    for prefix in prefixes(names):
        declare_muscle(node, prefix)
    return names, mode


def prefixes(names: list[str]) -> list[str]:
    """The parameter prefix of each muscle: ``<name>.``, or '' for the one muscle."""
    return [f'{name}.' for name in names] or ['']


def declare_muscle(
    node: Node, prefix: str, defaults: bool = True, read_only: bool = False
) -> None:
    """Declare one muscle's parameters under ``prefix`` and its selected model's block; without
    ``defaults`` unset ones stay unset (joint_node: a muscle ``file``'s values then apply);
    ``read_only`` for a node that never changes them.
    """
    for spec in PARAMETERS:
        if spec.per_muscle and not spec.name.startswith('models.'):
            declare_spec(node, replace(spec, read_only=read_only), prefix, defaults)
    model = block_of(node.get_parameter_or(prefix + 'model').value)  # unset: None
    if model in MODELS:
        declare_block(node, prefix, model, read_only=read_only)


def declare_block(
    node: Node, prefix: str, model: str, given: dict | None = None, read_only: bool = False
) -> None:
    """Declare ``models.<model>.*`` of the muscle under ``prefix``, each entry from ``given``
    (``{dotted name: value}``) if there, else from the parameter file if it sets it, else not
    declared (the file's absent entry: ``muscle.nominal_length``, no offset, no extrapolation).
    """
    for entry, table_spec in BLOCK_SPECS.items():
        spec = replace(table_spec, read_only=read_only)
        name = f'{prefix}models.{model}.{entry}'
        if node.has_parameter(name):  # configured again after a cleanup
            continue
        text = None
        if entry == 'params':
            m = MODELS[model]
            text = f'identified parameters {list(m.param_names)} of {model} ({m.equation}), SI'
        if given is not None and name in given:
            node.declare_parameter(name, given[name], descriptor(spec, text), ignore_override=True)
        elif overrides(node).get(name) is not None:  # else not declared: no unset parameter
            node.declare_parameter(name, TYPES[spec.kind], descriptor(spec, text))


def block_of(model: str | None) -> str | None:
    """The model whose block ``model`` selects: itself, or the model an alias names."""
    return ALIASES.get(model, model)


def expected_undeclared(name: str) -> bool:
    """Whether a parameter file's entry ``name`` is one a node reads without declaring it: a
    known model's block entry or identification result, or the muscle's given rest length (a
    record beside a calibrated one, :data:`~pma_model_ros.core.files.param_file.GIVEN_LENGTH`).
    """
    return _MODEL_ENTRY.fullmatch(name) is not None or name.endswith(f'muscle.{GIVEN_LENGTH}')


class ModelBlocks:
    """The model blocks of model_node's muscles, declared or not.

    ``stored`` holds every ``models.*`` entry of the parameter file, and a block's values as last
    set when it is undeclared (a switch of ``model``).  A request that sets an undeclared block's
    entries (``ros2 param load`` of a whole file) has them held (:meth:`hold`) for its validation
    (:meth:`would_be`) and stored once it succeeded (:meth:`applied`), which declares the block of
    every newly selected model.
    """

    def __init__(self, node: Node, names: list[str]) -> None:
        self.node, self.prefixes = node, prefixes(names)
        self.stored = {k: v for k, v in overrides(node).items() if expected_undeclared(k)}
        self.selected = {
            p: block_of(node.get_parameter_or(p + 'model').value) for p in self.prefixes
        }
        self._held: dict[str, object] = {}
        self.swapping = False  #: declarations of :meth:`applied` are in progress

    def hold(self, changes: list[Parameter]) -> list[Parameter]:
        """The changes to set as parameters; undeclared block entries are held, unless nothing
        else is set (then all are set, and rclpy refuses the undeclared ones).
        """
        kept = [p for p in changes if self.node.has_parameter(p.name)]
        held = {p.name: plain(p.value) for p in changes if not self.node.has_parameter(p.name)}
        if not kept or any(not expected_undeclared(name) for name in held):
            self._held = {}
            return changes
        self._held = held
        return kept

    def would_be(self, changes: list[Parameter]) -> dict[str, object]:
        """The whole parameter set ``{dotted name: value}`` once ``changes`` (and the held
        entries) are set.
        """
        return (
            self.stored
            | self._held
            | values(self.node)
            | {p.name: plain(p.value) for p in changes}
        )

    def applied(self) -> dict[str, object]:
        """After a successful set: store the held entries, swap the block of every muscle whose
        model changed; the whole parameter set.
        """
        self.stored.update(self._held)
        self._held = {}
        self.swapping = True
        try:
            for prefix, old in self.selected.items():
                new = block_of(self.node.get_parameter_or(prefix + 'model').value)
                if new == old:
                    continue
                block = [f'{prefix}models.{old}.{entry}' for entry in MODEL_BLOCK]
                if old in MODELS:
                    current = values(self.node)
                    self.stored.update({n: current[n] for n in block if n in current})
                    for name in block:
                        if self.node.has_parameter(name):
                            self.node.undeclare_parameter(name)
                declare_block(self.node, prefix, new, self.stored)
                self.selected[prefix] = new
        finally:
            self.swapping = False
        return self.stored | values(self.node)


def _check_names(names: list[str], mode: str) -> None:
    SPECS['input_mode'].check(mode)
    bad = [n for n in names if not _MUSCLE_NAME.fullmatch(n)]
    if bad:
        raise ValueError(
            f"parameter 'muscles': {bad[0]!r} is not a name (letters, digits, '_'; a letter first)"
        )
    if len(set(names)) != len(names):
        raise ValueError(f"parameter 'muscles': duplicate names in {names}")


def all_settings(
    flat: dict[str, object], names: list[str], instance: str = ''
) -> list[NodeSettings]:
    """Settings of every muscle of a would-be parameter set (one without ``names``; see
    :func:`~pma_model_ros.core.files.param_file.all_node_settings`, and its ``instance``).
    ValueError names the muscle and parameter.
    """
    for prefix in prefixes(names):
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
    return all_node_settings(nest(flat), instance=instance)
