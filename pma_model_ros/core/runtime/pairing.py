"""Pairing and freshness: after an input, which muscles have a pressure and a length to estimate
from (no ROS).

Times are integer nanoseconds on one clock (ROS time in a node, log time offline); a stamp is an
input's header stamp, ``now`` the clock when it is taken.  An input is fresh while
|now - stamp| <= ``max_age``.  Rules (``pairing``):

* ``every_input``: every valid input is answered with the newest valid pressure and length;
* ``approximate_time``: once per pair of a new pressure and a new length whose stamps lie within
  ``slop`` (message_filters' ApproximateTime for two inputs); of a pair further apart, the older
  input is dropped (``unpaired``).

A pair with a stale input gives no estimate (``stale``).  The rules are written twice, pinned equal
by ``test/test_core_engine.py``: over arrays of every muscle (:meth:`Pairing.pair`; an input of
every muscle at one stamp is kept as one number, so that its freshness is one comparison) and in
plain integers for one muscle (:meth:`Pairing.pair_one`, the one-muscle fast path).  Over a whole
recording, ``every_input`` is :meth:`Pairing.pair`'s array rule over the stream
(:func:`pair_every_input`), pinned to the engine by ``test/test_bags_estimate.py``;
``approximate_time`` runs :meth:`Pairing.pair_one` along it.  Freshness is :func:`fresh`
everywhere, on integers and on arrays.  How long an input waited in the node's queue, which a node
that fell behind uses to skip to its newest inputs, is :class:`QueueDelay`'s.
"""

from __future__ import annotations

import numpy as np

#: Stamp of an input never received [ns]: so far in the past that it is never fresh, and
#: now - NEVER still fits int64 for any time before 2116.
NEVER = -(1 << 62)
SECOND = 10**9  #: [ns]
#: A command's zero stamp [ns]: unstamped (robots often send commands with an empty header), taken
#: as received at ``now``; any other command stamp is age-checked as an input's.
UNSTAMPED = 0
PAIRINGS = ('every_input', 'approximate_time')
PRESSURE, LENGTH = 0, 1  #: rows of :attr:`Pairing.stamps`


def nanoseconds(seconds: float) -> int:
    """A duration [s] in integer nanoseconds."""
    return round(seconds * SECOND)


def fresh(stamps, now, max_age: int):
    """Whether ``stamps`` [ns] (an int or an array) are fresh at ``now`` [ns]: |now - stamp| <=
    ``max_age`` [ns].
    """
    return abs(now - stamps) <= max_age


def stale_command_stamps(stamps, now, max_age: int):
    """Whether command ``stamps`` [ns] (an int or an array) are stale at ``now`` [ns]: stamped
    (not :data:`UNSTAMPED`, taken as ``now``) and not :func:`fresh`.
    """
    # (^ True: not, for a bool and an array alike; np.logical_not costs 0.8 us on one stamp)
    return (stamps != UNSTAMPED) & (fresh(stamps, now, max_age) ^ True)


def _fresh_pairs(
    candidates: np.ndarray, p: np.ndarray, length: np.ndarray, now, max_age: int
) -> tuple[np.ndarray, np.ndarray]:
    """Of the ``candidates`` with both stamps [ns], (which estimate: both fresh at ``now`` [ns],
    which had a stale input).
    """
    candidates = candidates & (p != NEVER) & (length != NEVER)
    ok = fresh(p, now, max_age) & fresh(length, now, max_age)
    return candidates & ok, candidates & ~ok


def pair_every_input(
    p: np.ndarray, length: np.ndarray, now: np.ndarray, max_age: int
) -> tuple[np.ndarray, np.ndarray]:
    """``every_input`` over a stream of one muscle's valid inputs (``bag estimate``'s pass over a
    whole recording): with ``p`` and ``length`` the newest valid stamps [ns] after each input,
    taken at ``now`` [ns], (which estimate, which had a stale input).
    """
    return _fresh_pairs(np.ones(len(p), bool), p, length, now, max_age)


class Pairing:
    """The newest valid stamp of each muscle's pressure and length, and which are not yet paired
    (``approximate_time``).  An input concerns every muscle (``which`` None), those of a mask, or
    one muscle ``k`` (the ``_one`` methods).
    """

    def __init__(self, count: int, pairing: str, slop: int, max_age: int) -> None:
        if pairing not in PAIRINGS:
            raise ValueError(f"parameter 'pairing': unknown pairing {pairing!r}")
        self.approximate, self.slop, self.max_age = pairing == 'approximate_time', slop, max_age
        #: [ns] newest valid stamp of each muscle's pressure (row PRESSURE) and length (LENGTH)
        self.stamps = np.full((2, count), NEVER, np.int64)
        self._new = np.zeros((2, count), bool)
        #: per side, the one stamp of every muscle (the last input was of every muscle), or None
        self._common: list[int | None] = [NEVER, NEVER]
        #: no muscle, every muscle (read-only masks)
        self.none, self._all = np.zeros(count, bool), np.ones(count, bool)
        self.none.flags.writeable = self._all.flags.writeable = False

    def store(self, side: int, which: np.ndarray | None, stamp: int) -> None:
        """Valid inputs of ``side`` (PRESSURE or LENGTH) of every muscle (``which`` None) or of
        the muscles of the mask ``which``, stamped ``stamp`` [ns].
        """
        if which is None:
            self.stamps[side] = stamp
            self._common[side] = stamp
            if self.approximate:
                self._new[side] = True
        else:
            self.stamps[side, which] = stamp
            self._common[side] = None
            if self.approximate:
                self._new[side, which] = True

    def pair(
        self, which: np.ndarray | None, now: int
    ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """Which of the muscles whose input was just taken (``which``: a mask, None: all) estimate
        now (None: all of them); which of them had a stale input; which lost an input to ``slop``
        (:attr:`none` where no muscle did).
        """
        p, length = self._common
        if p is not None and length is not None and not self.approximate:
            if p == NEVER or length == NEVER:
                return self.none, self.none, self.none
            if fresh(p, now, self.max_age) and fresh(length, now, self.max_age):
                return which, self.none, self.none
            return self.none, (self._all if which is None else which), self.none
        candidates = self._all if which is None else which
        p, length = self.stamps
        unpaired = self.none
        if self.approximate:
            p_new, l_new = self._new
            candidates = candidates & p_new & l_new  # (a new stamp is a stamp, not NEVER)
            unpaired = candidates & (np.abs(p - length) > self.slop)
            older_p = unpaired & (p < length)
            p_new[older_p] = False
            l_new[unpaired & ~older_p] = False
            candidates &= ~unpaired
            p_new[candidates] = l_new[candidates] = False
        pairs, stale = _fresh_pairs(candidates, p, length, now, self.max_age)
        return pairs, stale, unpaired

    def common(self) -> int | None:
        """The newest stamp [ns] of the last pressure and length if each was one input of every
        muscle, else None.
        """
        p, length = self._common
        return None if p is None or length is None else max(p, length)

    def store_one(self, side: int, k: int, stamp: int) -> None:
        """:meth:`store` of muscle ``k`` alone."""
        self.stamps[side, k] = stamp
        self._common[side] = None
        if self.approximate:
            self._new[side, k] = True

    def pair_one(self, k: int, now: int) -> tuple[bool, bool, bool]:
        """:meth:`pair` of muscle ``k`` alone, whose input was just taken: (estimates, stale,
        unpaired).
        """
        p, length = self.stamps.item(PRESSURE, k), self.stamps.item(LENGTH, k)
        if p == NEVER or length == NEVER:
            return False, False, False
        if self.approximate:
            new = self._new
            if not (new.item(PRESSURE, k) and new.item(LENGTH, k)):
                return False, False, False
            if abs(p - length) > self.slop:
                new[PRESSURE if p < length else LENGTH, k] = False
                return False, False, True
            new[PRESSURE, k] = new[LENGTH, k] = False
        ok = fresh(p, now, self.max_age) and fresh(length, now, self.max_age)
        return ok, not ok, False


class QueueDelay:
    """How long each input of one topic waited before the node took it [ns]: the time since its
    publisher wrote it (DDS's source timestamp) less the topic's usual transport time.

    The usual transport time is the lowest reception-minus-source difference of the inputs
    received in the current and the previous :data:`WINDOW`, which also takes out a constant
    offset between the two machines' clocks and follows a step of either within two windows.
    Unlike the reception time alone, this counts a stall of the whole node process too: what was
    sent meanwhile is received, and stamped received, only when the process runs again.
    """

    #: [ns] How long one window of transport times lasts.
    WINDOW = SECOND

    def __init__(self) -> None:
        self._start = NEVER  # [ns] reception time of the current window's first input
        self._current = self._previous = 0  # [ns] lowest transport time of each window

    def waited(self, source: int, received: int, now: int) -> int:
        """The wait [ns] of an input written at ``source`` and received at ``received`` [ns],
        taken at ``now`` [ns] (each on its machine's system clock).
        """
        transport = received - source
        if received - self._start > self.WINDOW:
            first = self._start == NEVER
            self._previous = transport if first else self._current
            self._start, self._current = received, transport
        elif transport < self._current:
            self._current = transport
        return now - source - min(self._current, self._previous)
