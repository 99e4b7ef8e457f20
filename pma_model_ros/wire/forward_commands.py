"""The pressure commands of every muscle of a node as one ``std_msgs/Float64MultiArray``: what
ros2_control's forward_command_controller takes on ``<controller>/commands``, in the order of its
``joints`` (here: muscles, e.g. each with a ``pressure`` command interface), for joint_node (its
muscles, by name) and model_node (its muscles, by ``joint_name``; each muscle a group of one).

Such a controller writes a message's values to its command interfaces and holds them until the
next message, and it refuses a message whose size differs from its number of interfaces.  So a
message always carries every muscle of the order: a torque command that names only some joints
updates their muscles' values and repeats the others' last values (what the hardware holds
anyway).  Until every muscle of the order has had a command, nothing is published: no value would
be a guess.  Units as the muscles' ``pressure_command``: Pa, absolute or gauge by
``pressure_reference``.
"""

from __future__ import annotations

from typing import Sequence

from .cdr import float64_multi_array
from ..core.hints import did_you_mean


def forward_order(order: Sequence[str], names: Sequence[str], noun: str) -> list[str]:
    """The muscles of ``forward_command_order`` (empty: ``names``, the node's muscles in its
    order); ValueError for a name not among ``names`` (each a ``noun``), or one given twice.
    """
    for name in order:
        if name not in names:
            raise ValueError(
                f'forward_command_order: {name!r} is no {noun}{did_you_mean(name, names)}; '
                f'the muscles: {list(names)}'
            )
    if len(set(order)) != len(order):
        raise ValueError(f'forward_command_order: a muscle named twice in {list(order)}')
    return list(order or names)


class ForwardCommands:
    """The array of the muscles ``order``; ``muscles[k]``: group ``k``'s muscle names (a joint's
    two, or model_node's one muscle), in the order of its pressure commands.
    """

    def __init__(self, order: Sequence[str], muscles: Sequence[Sequence[str]]) -> None:
        place = {name: i for i, name in enumerate(order)}
        #: per joint, per muscle: its place in the array (None: not in the order)
        self.places = [[place.get(m) for m in names] for names in muscles]
        self._message = float64_multi_array(len(order))
        self.values = self._message.values  #: [Pa] the last command of each muscle of the order
        self._missing = set(range(len(order)))  # places of muscles without a command yet
        self._commanded = False

    def command(self, k: int, pressures: Sequence[float]) -> None:
        """Group ``k``'s new pressure commands [Pa]."""
        for i, value in zip(self.places[k], pressures):
            if i is not None:
                self.values[i] = value
                self._commanded = True
                self._missing.discard(i)

    def message(self) -> bytes | None:
        """After a command message: the array's bytes if a muscle of the order was
        commanded since the last message (its value repeated or not) and every muscle has a value,
        else None.
        """
        commanded, self._commanded = self._commanded, False
        return self._message.unstamped() if commanded and not self._missing else None
