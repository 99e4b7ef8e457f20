"""joint_node: torque and stiffness estimates and pressure commands of antagonistic joints.

Parameters: a joint file (``config/example_joint.yaml``, layout in
:mod:`pma_model_ros.core.files.joint_file`), read by the ``configure`` transition: all read-only.
The node is managed (:mod:`.managed`) and answers only while active.  Topics (relative, so a
namespace applies; pressures absolute, or gauge with ``pressure_reference: gauge``):

* in ``joint_states`` (sensor_msgs/JointState: position θ [rad], entries by joint name; the
  velocity is not used: a hysteresis muscle's branch follows its length or pressure with memory)
  and each muscle's ``<muscle>/pressure`` (sensor_msgs/FluidPressure, absolute Pa), or with
  ``pressure_input: joint_state`` one ``muscle_pressures`` (sensor_msgs/JointState: an entry per
  muscle by its name, the pressure in ``pressure_field``, as ros2_control's
  joint_state_broadcaster publishes a ``pressure`` state interface), read as model_node's
  combined ``muscle_pressures`` (:mod:`pma_model_ros.wire.joint_state`);
* out, once per joint_states message, for its joints whose pressures are fresh: ``torque_estimate``
  (JointState: effort = torque [N·m], positive counter-clockwise) and ``stiffness_estimate``
  (JointState: effort = K = -dτ/dθ [N·m/rad]), both with the joint_states stamp; ``/diagnostics``
  (one status per joint, named ``<namespace>/joint_node: <joint>``, ``hardware_id`` the joint's
  parameter, by default ``/<namespace>/joint_node/<joint>``;
  1 Hz and when a level changes, as model_node's);
* commands: ``torque_command`` (JointState: effort = wanted torque [N·m]) → each muscle's
  ``<muscle>/pressure_command`` (FluidPressure, absolute Pa), at the newest angle, with the joint's
  co-contraction level, or with its wanted stiffness once a ``stiffness_command`` (JointState:
  effort = K [N·m/rad]) arrived; a ``cocontraction_command`` (JointState: effort = level [Pa
  gauge]) returns to co-contraction;
* with ``forward_command_topic``: also every muscle's pressure command [Pa, as
  ``pressure_command``] in one std_msgs/Float64MultiArray per torque command, in
  ``forward_command_order``, for ros2_control's forward_command_controller
  (:mod:`pma_model_ros.wire.forward_commands`: the others' last values; nothing until every muscle
  had a command).  Every decision is the
  :class:`~pma_model_ros.core.runtime.joint_engine.JointEngine`'s.
"""

from __future__ import annotations

from functools import partial
import sys

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64MultiArray

from . import model_params, parameters
from .managed import ManagedNode
from .model_node import DESERIALIZE
from .qos import publisher, RELIABLE, SENSOR_INPUT, subscription, warn_unknown_overrides
from .startup import run
from ..core.files.joint_file import (
    identification,
    joint_file_of,
    joints,
    muscle_folder,
)
from ..core.files.joint_node_parameters import (
    JOINT_MUSCLE_PARAMETERS,
    JOINT_NODE_PARAMETERS,
    JOINT_PARAMETERS,
)
from ..core.files.shipped_data import share_directory
from ..core.runtime.health import node_timing
from ..core.runtime.joint_engine import JointEngine, Settings
from ..wire.cdr import fluid_pressure, joint_state, MALFORMED, MalformedMessage
from ..wire.forward_commands import forward_order, ForwardCommands
from ..wire.joint_state import JointIndex, JointStateArrays, JointStateReader
from ..wire.muscle_inputs import stamped_value

SPECS_BY_NAME = {spec.name: spec for spec in JOINT_NODE_PARAMETERS}


def declare(node: Node) -> None:
    """Declare every joint_node parameter, read-only: node-wide, per joint, per muscle (by file or
    inline; a model's block only where the muscle names its ``model`` inline).  ``config_dir``
    holds the folder the muscle files are read from (:func:`muscle_folder`), absolute, so that
    ``ros2 param dump``'s file loads them from anywhere.
    """
    if not node.has_parameter('config_dir'):
        folder = muscle_folder(
            str(parameters.overrides(node).get('config_dir') or ''),
            joint_file_of(sys.argv),
            share_directory() / 'config',
        )
        node.declare_parameter(
            'config_dir',
            str(folder.resolve()),
            parameters.descriptor(SPECS_BY_NAME['config_dir']),
            ignore_override=True,
        )
    names = parameters.declare_table(node, JOINT_NODE_PARAMETERS)['joints'] or []
    for joint in names:
        for muscle in (
            parameters.declare_table(node, JOINT_PARAMETERS, f'{joint}.')['muscles'] or []
        ):
            parameters.declare_table(node, JOINT_MUSCLE_PARAMETERS, f'{joint}.{muscle}.')
            model_params.declare_muscle(node, f'{joint}.{muscle}.', defaults=False, read_only=True)


class JointNode(ManagedNode):
    """Thin ROS shell around one :class:`JointEngine` for all its joints; a managed node
    (:mod:`.managed`): it answers inputs only while active.
    """

    def __init__(self, **kwargs) -> None:
        self.engine: JointEngine | None = None
        super().__init__('joint_node', **kwargs)

    def declare_all(self) -> None:
        declare(self)

    def status_names(self) -> list[tuple[str, str]]:
        return list(zip(self._names, self._hardware))

    def configure(self) -> None:
        """Read and check the parameters, build the engine, warn about unknown parameters; then,
        last, create every ROS entity (nothing is matched before the node can answer).
        """
        declare(self)
        # the overrides: also what is not declared, e.g. an inline muscle's other models
        flat = parameters.overrides(self) | parameters.values(self)
        nested = parameters.nest(flat)
        base = muscle_folder(
            flat.get('config_dir') or '', joint_file_of(sys.argv), share_directory() / 'config'
        )
        found = joints(nested, base)
        self.identification = [identification(j, nested, base) for j in found]
        settings = [
            Settings(
                float(nested[j.name]['cocontraction']),
                str(nested[j.name]['cocontraction_mode']),
            )
            for j in found
        ]
        self._new_engine = partial(
            JointEngine,
            found,
            settings,
            float(flat['ambient_pressure']),
            float(flat['max_input_age']),
            **node_timing(len(found)),
            pressure_reference=str(flat['pressure_reference']),
        )
        self._pressure_index = self._pressure_index_of(flat, found)
        topic = str(flat['forward_command_topic'])
        self._forward_order = (
            forward_order(
                list(flat['forward_command_order'] or []),
                [m for j in found for m in j.muscle_names],
                'muscle of the joints',
            )
            if topic
            else None
        )
        self.reset()
        self._hardware = [
            str(nested[j.name].get('hardware_id') or f'{self.instance}/{j.name}') for j in found
        ]
        self._names = [j.name for j in found]
        # prebuilt answers of every joint (the usual joint_states), and each muscle's command
        self._all = [joint_state(self._names, 'effort') for _ in range(2)]
        self._commands = [[fluid_pressure(m) for m in j.muscle_names] for j in found]
        self._readers = {
            topic: JointStateReader(DESERIALIZE['JointState'])
            for topic in (
                'joint_states',
                'muscle_pressures',
                'torque_command',
                'stiffness_command',
                'cocontraction_command',
            )
        }
        parameters.warn_unknown(self, model_params.expected_undeclared)  # inline muscles' models
        self.get_logger().info(
            '; '.join(
                f"joint '{j.name}': {j.muscle_names[0]} ({j.muscles[0].model.name}) "
                f'shortens for positive angle, {j.muscle_names[1]} ({j.muscles[1].model.name})'
                for j in found
            )
        )
        self.create_interfaces()

    def reset(self) -> None:
        """A fresh engine (no input known, co-contraction levels from the parameters), and no
        forwarded command known.
        """
        self.engine = self._new_engine()
        self._forward = (
            ForwardCommands(self._forward_order, [j.muscle_names for j in self.engine.joints])
            if self._forward_order
            else None
        )

    def release(self) -> None:
        self.engine = self._new_engine = self._forward = None
        self._command_pubs = []

    def create_interfaces(self) -> None:
        """Every subscription and publisher of the node (raw subscriptions: bytes in), each QoS
        overridable by parameters (:mod:`.qos`).
        """
        self._torque_pub = publisher(self, JointState, 'torque_estimate', RELIABLE)
        self._stiffness_pub = publisher(self, JointState, 'stiffness_estimate', RELIABLE)
        self._diag_pub = publisher(self, DiagnosticArray, '/diagnostics', RELIABLE)
        if self._forward_order:
            topic = self.get_parameter('forward_command_topic').value
            self._forward_pub = publisher(self, Float64MultiArray, topic, RELIABLE)
        self._command_pubs = []
        for k, joint in enumerate(self.engine.joints):
            pubs = []
            for m, muscle in enumerate(joint.muscle_names):
                if self._pressure_index is None:
                    callback = partial(self._on_pressure, k, m)
                    subscription(
                        self, FluidPressure, f'{muscle}/pressure', callback, SENSOR_INPUT, raw=True
                    )
                pubs.append(publisher(self, FluidPressure, f'{muscle}/pressure_command', RELIABLE))
            self._command_pubs.append(pubs)
        if self._pressure_index is not None:
            subscription(
                self, JointState, 'muscle_pressures', self._on_pressures, SENSOR_INPUT, raw=True
            )
        subscription(self, JointState, 'joint_states', self._on_states, SENSOR_INPUT, raw=True)
        subscription(self, JointState, 'torque_command', self._on_torque, RELIABLE, raw=True)
        for topic in ('stiffness_command', 'cocontraction_command'):
            callback = partial(self._on_level, topic)
            subscription(self, JointState, topic, callback, RELIABLE, raw=True)
        warn_unknown_overrides(self, parameters.overrides(self))

    # --- callbacks: bytes in, bytes out, only while active (the gate: the first line)
    def _on_pressure(self, k: int, m: int, data: bytes) -> None:
        if not self.active:
            return
        now = self.now()
        try:
            stamp, value = stamped_value(data, DESERIALIZE['FluidPressure'], 'fluid_pressure')
        except MalformedMessage:
            self.engine.reject(k, 'pressure', MALFORMED, now)
        else:
            self.engine.pressure(k, m, value, stamp, now)
        self.report(now)

    def _on_pressures(self, data: bytes) -> None:
        """A ``muscle_pressures`` JointState: each muscle's pressure it holds, as
        :meth:`_on_pressure`; a muscle it gives no value of is rejected with the reason.
        """
        if not self.active:
            return
        now, engine = self.now(), self.engine
        if (msg := self._read('muscle_pressures', data, 'pressure', now)) is None:
            return self.report(now)
        take, present, problems = self._pressure_index.of(msg)
        values = getattr(msg, self._pressure_index.field)[take].tolist()
        if present is None:
            for (k, m), value in zip(self._muscles, values):
                engine.pressure(k, m, value, msg.stamp, now)
        else:
            problem = iter(problems)
            for (k, m), value, here in zip(self._muscles, values, present.tolist()):
                if here:
                    engine.pressure(k, m, value, msg.stamp, now)
                else:
                    engine.reject(k, 'pressure', next(problem), now)
        self.report(now)

    def _on_states(self, data: bytes) -> None:
        if not self.active:
            return
        now = self.now()
        if (msg := self._read('joint_states', data, 'joint_states', now)) is None:
            return self.report(now)
        done, torques, stiffnesses = self.engine.joint_states(
            msg.names, msg.position.tolist(), msg.stamp, now
        )
        if done:
            every = done == self._names
            for pub, template, values in zip(
                (self._torque_pub, self._stiffness_pub), self._all, (torques, stiffnesses)
            ):
                out = template if every else joint_state(done, 'effort')
                out.values[:] = values
                pub.publish(out(msg.stamp))
        self.report(now)

    def _on_torque(self, data: bytes) -> None:
        if not self.active:
            return
        now, forward = self.now(), self._forward
        if (msg := self._read('torque_command', data, 'command', now)) is None:
            return self.report(now)
        for name, torque in self._entries(msg, now):
            k = self.engine.index[name]
            absolute = self.engine.command(k, torque, now, msg.stamp)
            if absolute is not None:
                for pub, value, template in zip(
                    self._command_pubs[k], absolute, self._commands[k]
                ):
                    template.values[0] = value
                    pub.publish(template(now))
                if forward is not None:
                    forward.command(k, absolute)
        if forward is not None and (message := forward.message()) is not None:
            self._forward_pub.publish(message)
        self.report(now)

    def _on_level(self, topic: str, data: bytes) -> None:
        """A ``stiffness_command`` or ``cocontraction_command``: the engine's method of that name
        sets how the next torque commands are made.
        """
        if not self.active:
            return
        now = self.now()
        if (msg := self._read(topic, data, 'command', now)) is None:
            return self.report(now)
        apply = getattr(self.engine, topic.removesuffix('_command'))
        for name, value in self._entries(msg, now):
            apply(self.engine.index[name], value, now, msg.stamp)
        self.report(now)

    def _pressure_index_of(self, flat: dict, found: list) -> JointIndex | None:
        """With ``pressure_input: joint_state``: where each muscle's pressure sits in a
        ``muscle_pressures`` JointState (:attr:`_muscles`: its (joint, muscle) of each entry).
        """
        self._muscles = [(k, m) for k, j in enumerate(found) for m, _ in enumerate(j.muscle_names)]
        source, field = (
            SPECS_BY_NAME[name].check(str(flat[name]))
            for name in ('pressure_input', 'pressure_field')
        )
        if source == 'per_muscle':
            return None
        return JointIndex([name for j in found for name in j.muscle_names], field)

    def _read(self, topic: str, data: bytes, source: str, now: int) -> JointStateArrays | None:
        """A JointState of ``topic``; None if its deserializer refused it, then rejected for
        every joint as an input of ``source``.
        """
        try:
            return self._readers[topic](data)
        except MalformedMessage:
            for k in range(len(self.engine.joints)):
                self.engine.reject(k, source, MALFORMED, now)
            return None

    def _entries(self, msg: JointStateArrays, now: int) -> list[tuple[str, float]]:
        """(joint, effort) of a command's entries of this node's joints; mismatched arrays are
        rejected.
        """
        ours = [n for n in msg.names if n in self.engine.index]
        if len(msg.effort) != len(msg.names):
            for name in ours:
                self.engine.reject(
                    self.engine.index[name],
                    'command',
                    f'command: {len(msg.names)} names, {len(msg.effort)} efforts',
                    now,
                )
            return []
        return [(n, e) for n, e in zip(msg.names, msg.effort.tolist()) if n in self.engine.index]

    def publish_status(self, now: int) -> None:
        """One DiagnosticStatus per joint in one DiagnosticArray."""
        entries = [
            (joint.name, hardware, status.level, status.message, status.values | ident)
            for joint, hardware, status, ident in zip(
                self.engine.joints, self._hardware, self.engine.statuses(now), self.identification
            )
        ]
        self.publish_entries(entries, now)


def main(args: list[str] | None = None) -> int:
    return run('joint_node', JointNode, args)


if __name__ == '__main__':
    sys.exit(main())
