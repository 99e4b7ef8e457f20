"""Which hysteresis branch a muscle is on: a play operator (backlash) with memory and a deadband
(no ROS).

The branch is +1 after the followed signal rose (lengthening, or filling) and -1 after it fell
(shortening, or venting).  It changes only when the signal reverses by more than ``deadband`` from
the extreme of its current run, is kept while the signal holds still, and is 0 (unknown) only
before the signal first moved by more than the deadband.  Velocity noise around zero cannot flip
it.

Sárosi's DMSP-10-100 loop follows the length (force against contraction); test rigs that fill and
vent at a fixed length follow the pressure.  :func:`play` is the elementwise rule for floats and
arrays (many muscles, one sample each); :func:`branches` runs it along a time series.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

#: What a hysteresis model's branches follow.
INPUTS = ('length', 'pressure')


class Follow(NamedTuple):
    """What one muscle's branch follows: ``input`` (one of :data:`INPUTS`) and the play
    operator's ``deadband`` [m for the length, Pa gauge for the pressure].
    """

    input: str
    deadband: float


#: The names of the two branches of each input: (+1, -1), the followed signal rising and falling.
#: Which of them is the upper (the larger force) is a property of a muscle's data: lengthening is
#: usually the upper one (Sárosi's loop), filling at a held length the lower one.
BRANCH_NAMES = {'length': ('lengthening', 'shortening'), 'pressure': ('filling', 'venting')}


def branch_name(follow: str, branch: float) -> str:
    """The name of ``branch`` (+1 or -1) of a model whose branches follow ``follow``."""
    return BRANCH_NAMES[follow][0 if branch > 0 else 1]


def branch_of(follow: str, name: str) -> float:
    """The branch (+1 or -1) called ``name``; ValueError naming the branches ``follow`` has."""
    names = BRANCH_NAMES[follow]
    if name not in names:
        raise ValueError(
            f'the branches follow the {follow}: {names[0]} or {names[1]}, not {name!r}'
        )
    return 1.0 if name == names[0] else -1.0


#: The play operator's deadband of each input unless a muscle's parameters say otherwise [m, Pa]
#: (the defaults of ``hysteresis.<input>_deadband``).
DEFAULT_DEADBANDS = {'length': 0.0005, 'pressure': 5000.0}
#: What a hysteresis muscle's branch follows unless its parameters say otherwise.
DEFAULT_FOLLOW = Follow('length', DEFAULT_DEADBANDS['length'])


def play(branch, anchor, value, deadband):
    """One step of the play operator: the new (branch, anchor) after the signal reads ``value``.

    ``anchor`` is the extreme of the current run (NaN before the first sample); ``branch`` +1, -1
    or 0. Floats in, floats out (one muscle); arrays in, arrays out (elementwise).  A non-finite
    ``value`` changes nothing.
    """
    if isinstance(value, float):
        if not math.isfinite(value):
            return branch, anchor
        if anchor != anchor:  # NaN: the first sample
            return branch, value
        if value - anchor > deadband and branch <= 0 or value > anchor and branch > 0:
            return 1.0, value
        if anchor - value > deadband and branch >= 0 or value < anchor and branch < 0:
            return -1.0, value
        return branch, anchor
    value = np.asarray(value, float)
    with np.errstate(invalid='ignore'):
        seen = np.isfinite(value)
        first = seen & np.isnan(anchor)
        up = (
            seen
            & ~first
            & ((value - anchor > deadband) & (branch <= 0) | (value > anchor) & (branch > 0))
        )
        down = (
            seen
            & ~first
            & ((anchor - value > deadband) & (branch >= 0) | (value < anchor) & (branch < 0))
        )
    return (
        np.where(up, 1.0, np.where(down, -1.0, branch)),
        np.where(first | up | down, value, anchor),
    )


def branches(values: ArrayLike, deadband: float) -> np.ndarray:
    """The branch (+1, -1, 0) after each sample of a time series ``values``."""
    branch, anchor, out = 0.0, math.nan, []
    for value in np.asarray(values, float).tolist():
        branch, anchor = play(branch, anchor, value, deadband)
        out.append(branch)
    return np.array(out)
