"""model_node's input messages, as bytes, into its
:class:`~pma_model_ros.core.runtime.engine.Engine`, and its answers as bytes: the one translation
the node and ``bag estimate`` share.

Per muscle ``k``: ``pressure`` (FluidPressure), ``muscle_state`` (JointState, the entry of the
muscle's joint name) and ``force_command`` (WrenchStamped), and with a
:attr:`MuscleInputs.residual` monitor ``measured_force`` (WrenchStamped, force.x).  Combined:
``muscle_pressures`` and ``muscle_states`` (JointStates of every muscle), ``force_commands`` and
``measured_forces`` (JointState efforts).  A
JointState that lacks a muscle, or whose arrays do not match, rejects only the muscles it gives no
value for.  ``deserialize[type]`` decodes what the fast readers cannot (types: ``FluidPressure``,
``JointState``, ``WrenchStamped``); a message it refuses is rejected as ``malformed message`` for
the muscles of its topic (every muscle, for a combined one), and nothing is answered from it.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

from .cdr import (
    decode,
    FLOATS,
    joint_state,
    MALFORMED,
    MalformedMessage,
    stamp_ns,
    stamped_float,
    Template,
    wrench_stamped,
)
from .joint_state import JointIndex, JointStateReader
from ..core.runtime.engine import Engine
from ..core.runtime.residual import Residuals, Taken

Deserializers = dict[str, Callable[[bytes], object]]
_IN_ORDER = slice(None)  #: a JointState's values are the muscles', in their order


def stamped_value(data: bytes, deserialize: Callable[[bytes], object], field: str):
    """(stamp [ns], value) of a FluidPressure (``fluid_pressure``) or WrenchStamped (``force``);
    raises :class:`~.cdr.MalformedMessage` for bytes the deserializer refuses.
    """
    fast = stamped_float(data, FLOATS[field])
    if fast is not None:
        return fast
    msg = decode(deserialize, data)
    value = msg.fluid_pressure if field == 'fluid_pressure' else msg.wrench.force.x
    return stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec), float(value)


class MuscleInputs:
    """Inputs of the muscles of ``engine`` (``joints``: their JointState names, in its order)."""

    def __init__(
        self,
        engine: Engine,
        joints: Sequence[str],
        frames: Sequence[str],
        deserialize: Deserializers,
        residual: Residuals | None = None,
    ) -> None:
        self.engine, self.joints, self._deserialize = engine, list(joints), deserialize
        #: the measured forces' monitor (None: no measured force is read)
        self.residual = residual
        read = deserialize['JointState']
        self._states = [JointStateReader(read) for _ in joints]  # per muscle
        self._state_index = [JointIndex([j]) for j in joints]
        self._combined = {
            name: (JointStateReader(read), JointIndex(joints, field))
            for name, field in (
                ('muscle_pressures', 'position'),
                ('muscle_states', 'position'),
                ('force_commands', 'effort'),
                ('measured_forces', 'effort'),
            )
        }
        #: per muscle: force_estimate (WrenchStamped, its frame_id)
        self.estimates = [wrench_stamped(frame) for frame in frames]
        self._all = joint_state(joints, 'effort')  # force_estimates of every muscle
        self._unknown = np.full(len(joints), math.nan)  # rates of a muscle_states without
        self._unknown.flags.writeable = False
        self.commanded: list[int] = []  #: the muscles of the last force_commands answered

    # --- per muscle
    def pressure(self, k: int, data: bytes, now: int) -> bytes | None:
        """A ``pressure`` message of muscle ``k``: its force_estimate, if any."""
        try:
            read = self._deserialize['FluidPressure']
            stamp, value = stamped_value(data, read, 'fluid_pressure')
        except MalformedMessage:
            self.engine.reject(k, 'pressure', MALFORMED, now)
            return None
        return self._one(k, self.engine.pressure(k, value, stamp, now))

    def muscle_state(self, k: int, data: bytes, now: int) -> bytes | None:
        """A ``muscle_state`` JointState of muscle ``k``: its force_estimate, if any."""
        try:
            msg = self._states[k](data)
        except MalformedMessage:
            self.engine.reject(k, 'muscle_state', MALFORMED, now)
            return None
        take, present, problems = self._state_index[k].of(msg)
        if present is not None:
            self.engine.reject(k, 'muscle_state', problems[0], now)
            return None
        i = take.item(0)
        rate = msg.velocity.item(i) if len(msg.velocity) else math.nan
        return self._one(
            k,
            self.engine.length(
                k,
                msg.position.item(i),
                rate if math.isfinite(rate) else math.nan,
                msg.stamp,
                now,
            ),
        )

    def _one(self, k: int, estimated: bool) -> bytes | None:
        if not estimated:
            return None
        template = self.estimates[k]
        template.values[0] = self.engine.forces.item(0)
        return template(self.engine.stamp)

    def force_command(self, k: int, data: bytes, now: int) -> float | None:
        """A ``force_command`` of muscle ``k``: the pressure command [Pa], if any."""
        try:
            stamp, force = stamped_value(data, self._deserialize['WrenchStamped'], 'force')
        except MalformedMessage:
            self.engine.reject(k, 'force_command', MALFORMED, now)
            return None
        return self.engine.command(k, force, now, stamp)

    def served(self, muscle: int | None) -> None:
        """Keep the estimate just answered, of muscle ``muscle`` (None: of a combined input, every
        muscle it estimated), for the measured force of its stamp (:attr:`residual`).
        """
        engine = self.engine
        if muscle is not None:
            gauge, length, _ = engine.inputs(muscle)
            self.residual.served(
                muscle, engine.stamp, engine.forces.item(0), gauge, length, engine.flags.item(0)
            )
        else:
            m = engine.muscles
            self.residual.served_all(
                engine.stamp,
                None if engine.every else engine.estimated,
                engine.forces,
                m.pressure - m.ambient,
                m.length,
                engine.flags,
            )

    def measured_force(self, k: int, data: bytes, now: int) -> tuple[float, float, float] | None:
        """A ``measured_force`` of muscle ``k`` into :attr:`residual`: (gauge pressure [Pa],
        length [m], force [N]) of the sample if it entered the window.
        """
        try:
            stamp, force = stamped_value(data, self._deserialize['WrenchStamped'], 'force')
        except MalformedMessage:
            self.residual.reject(k, MALFORMED)
            return None
        return self.residual.measured(k, stamp, force, now)

    # --- combined
    def pressures(self, data: bytes, now: int) -> bytes | None:
        """A ``muscle_pressures`` JointState (absolute pressures [Pa] in ``position``): the
        force_estimates of the muscles estimated, if any.
        """
        msg, take, present = self._read('muscle_pressures', data, 'pressure', now)
        if take is None:
            return None
        values = msg.position if take is _IN_ORDER else msg.position[take]
        return self._many(self.engine.pressures(values, msg.stamp, now, present))

    def states(self, data: bytes, now: int) -> bytes | None:
        """A ``muscle_states`` JointState (lengths [m], rates [m/s] or empty): see
        :meth:`pressures`.
        """
        msg, take, present = self._read('muscle_states', data, 'muscle_state', now)
        if take is None:
            return None
        lengths = msg.position if take is _IN_ORDER else msg.position[take]
        if len(msg.velocity):
            rates = msg.velocity if take is _IN_ORDER else msg.velocity[take]
            if not math.isfinite(rates.sum()):  # inf or NaN: unknown
                rates = np.where(np.isfinite(rates), rates, math.nan)
        else:
            rates = self._unknown
        return self._many(self.engine.lengths(lengths, rates, msg.stamp, now, present))

    def _read(self, topic: str, data: bytes, source: str, now: int):
        """(message, where each muscle's value is: _IN_ORDER, None if none; present)."""
        reader, index = self._combined[topic]
        try:
            msg = reader(data)
        except MalformedMessage:
            self._reject_all(source, now)
            return None, None, None
        take, present, problems = index.of(msg)
        if present is not None:
            for k, problem in zip(np.flatnonzero(~present).tolist(), problems):
                self.engine.reject(k, source, problem, now)
            if not present.any():
                return msg, None, present
        return msg, (_IN_ORDER if index.in_order(msg) else take), present

    def _reject_all(self, source: str, now: int) -> None:
        """A combined message of ``source`` its deserializer refused: rejected for every muscle."""
        for k in range(len(self.joints)):
            self.engine.reject(k, source, MALFORMED, now)

    def _many(self, estimated: np.ndarray) -> bytes | None:
        engine = self.engine
        if engine.every:
            self._all.values[:] = engine.forces
            return self._all(engine.stamp)
        if not estimated.any():
            return None
        some = joint_state([j for j, e in zip(self.joints, estimated.tolist()) if e], 'effort')
        some.values[:] = engine.forces[estimated]
        return some(engine.stamp)

    def force_commands(self, data: bytes, now: int) -> Template | None:
        """A ``force_commands`` JointState (wanted tensions [N] in ``effort``): the
        pressure_commands (JointState, absolute Pa in ``position``; stamp it), if any; then
        :attr:`commanded` holds the muscles it commanded, in its ``values``' order.
        """
        reader, index = self._combined['force_commands']
        try:
            msg = reader(data)
        except MalformedMessage:
            self._reject_all('force_command', now)
            return None
        take, present, problems = index.of(msg)
        commanded, pressures = [], []
        for k, joint in enumerate(self.joints):
            if joint not in msg.names:
                continue
            if present is not None and not present[k]:
                self.engine.reject(k, 'force_command', problems[0], now)
            elif (
                pressure := self.engine.command(k, float(msg.effort[take[k]]), now, msg.stamp)
            ) is not None:
                commanded.append(k)
                pressures.append(pressure)
        if not commanded:
            return None
        self.commanded = commanded
        out = joint_state([self.joints[k] for k in commanded], 'position')
        out.values[:] = pressures
        return out

    def measured_forces(self, data: bytes, now: int) -> Taken:
        """A ``measured_forces`` JointState (measured tensions [N] in ``effort``; the muscles it
        does not name are not measured) into :attr:`residual`: the muscles, gauge pressures [Pa],
        lengths [m] and forces [N] of the samples that entered the window.
        """
        reader, index = self._combined['measured_forces']
        try:
            msg = reader(data)
        except MalformedMessage:
            for k in range(len(self.joints)):
                self.residual.reject(k, MALFORMED)
            return []
        take, present, problems = index.of(msg)
        if present is None:
            ks = np.arange(len(self.joints))
        else:
            named = np.array([joint in msg.names for joint in self.joints])
            for k in np.flatnonzero(named & ~present).tolist():
                self.residual.reject(k, problems[0])
            ks = np.flatnonzero(present)
        forces = np.asarray(msg.effort, float)[take[ks]]
        return self.residual.measured_all(ks, msg.stamp, forces, now)
