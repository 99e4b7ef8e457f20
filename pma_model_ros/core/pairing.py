"""Pairing and freshness: after an input, which muscles have a pressure and a length to estimate
from (no ROS).

Times are integer nanoseconds on one clock (ROS time in a node, log time offline); a stamp is an
input's header stamp, ``now`` the clock when it is taken.  An input is fresh while
|now - stamp| <= ``max_age``.  Rules (``pairing``):

* ``every_input``: every valid input is answered with the newest valid pressure and length;
* ``approximate_time``: once per pair of a new pressure and a new length whose stamps lie within
  ``slop`` (message_filters' ApproximateTime for two inputs); of a pair further apart, the older
  input is dropped (``unpaired``).

A pair with a stale input gives no estimate (``stale``).
"""

from __future__ import annotations

import numpy as np

#: Stamp of an input never received [ns]: so far in the past that it is never fresh, and
#: now - NEVER still fits int64 for any time before 2116.
NEVER = -(1 << 62)
SECOND = 10**9  #: [ns]
PAIRINGS = ('every_input', 'approximate_time')
PRESSURE, LENGTH = 0, 1  #: rows of :attr:`Pairing.stamps`


def nanoseconds(seconds: float) -> int:
    """A duration [s] in integer nanoseconds."""
    return round(seconds * SECOND)


def fresh(stamps: np.ndarray, now: int, max_age: int) -> np.ndarray:
    """Which ``stamps`` [ns] are fresh at ``now`` [ns]: |now - stamp| <= ``max_age`` [ns]."""
    return np.abs(now - stamps) <= max_age


class Pairing:
    """The newest valid stamp of each muscle's pressure and length, and which are not yet paired
    (``approximate_time``).  Muscles are addressed by a slice ``sel`` and masks over it.
    """

    def __init__(self, count: int, pairing: str, slop: int, max_age: int) -> None:
        if pairing not in PAIRINGS:
            raise ValueError(f"parameter 'pairing': unknown pairing {pairing!r}")
        self.approximate, self.slop, self.max_age = pairing == 'approximate_time', slop, max_age
        #: [ns] newest valid stamp of each muscle's pressure (row PRESSURE) and length (LENGTH)
        self.stamps = np.full((2, count), NEVER, np.int64)
        self._new = np.zeros((2, count), bool)
        self._both = False  # every muscle has had both inputs (then it stays so)

    def store(self, side: int, sel: slice, valid: np.ndarray | None, stamp: int) -> None:
        """Valid inputs of ``side`` (PRESSURE or LENGTH) of the muscles ``sel`` (``valid``: a
        mask over them, None: all), stamped ``stamp`` [ns].
        """
        if valid is None:
            self.stamps[side, sel] = stamp
            self._new[side, sel] = True
        else:
            self.stamps[side, sel][valid] = stamp
            self._new[side, sel][valid] = True

    def pair(
        self, sel: slice, candidates: np.ndarray, now: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Which of the muscles ``sel`` whose input was just taken (``candidates``) estimate now;
        which of them had a stale input; which lost an input to ``slop`` (None: none can).
        """
        p, length = self.stamps[PRESSURE, sel], self.stamps[LENGTH, sel]
        if not self._both:
            self._both = bool((self.stamps != NEVER).all())
            candidates = candidates & (p != NEVER) & (length != NEVER)
        unpaired = None
        if self.approximate:
            p_new, l_new = self._new[PRESSURE, sel], self._new[LENGTH, sel]
            candidates = candidates & p_new & l_new
            unpaired = candidates & (np.abs(p - length) > self.slop)
            older_p = unpaired & (p < length)
            p_new[older_p] = False
            l_new[unpaired & ~older_p] = False
            candidates &= ~unpaired
            p_new[candidates] = l_new[candidates] = False
        ok = fresh(p, now, self.max_age) & fresh(length, now, self.max_age)
        stale = candidates & ~ok
        return candidates & ok, stale, unpaired
