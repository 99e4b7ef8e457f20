"""joint_node: torque and stiffness estimates and pressure commands of antagonistic joints.

Parameters: a joint file (``config/example_joint.yaml``, layout in
:mod:`pma_model_ros.core.joint_file`), read at start-up: all read-only.  Topics (relative, so
a namespace applies; pressures absolute, or gauge with ``pressure_reference: gauge``):

* in ``joint_states`` (sensor_msgs/JointState: position θ [rad], entries by joint name; the
  velocity is not used: a hysteresis muscle's branch follows its length or pressure with memory)
  and each muscle's ``<muscle>/pressure`` (sensor_msgs/FluidPressure, absolute Pa);
* out, once per joint_states message, for its joints whose pressures are fresh: ``torque_estimate``
  (JointState: effort = torque [N·m], positive counter-clockwise) and ``stiffness_estimate``
  (JointState: effort = K = -dτ/dθ [N·m/rad]), both with the joint_states stamp; ``/diagnostics``
  (one status per joint, 1 Hz);
* commands: ``torque_command`` (JointState: effort = wanted torque [N·m]) → each muscle's
  ``<muscle>/pressure_command`` (FluidPressure, absolute Pa), at the newest angle, with the joint's
  co-contraction level, or with its wanted stiffness once a ``stiffness_command`` (JointState:
  effort = K [N·m/rad]) arrived; a ``cocontraction_command`` (JointState: effort = level [Pa
  gauge]) returns to co-contraction.  Every decision is the
  :class:`~pma_model_ros.core.joint_engine.JointEngine`'s.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
import sys

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, JointState

from . import model_params, parameters
from .diagnostics import diagnostic_array
from .model_node import DIAGNOSTIC_PERIOD, INPUT_QOS
from .startup import refusing, run
from ..core.cdr import sentinels, StampedTemplate
from ..core.engine import seconds
from ..core.joint_engine import JointEngine, Settings
from ..core.joint_file import (
    identification,
    JOINT_PARAMETERS,
    joints,
    MUSCLE_PARAMETERS,
    NODE_PARAMETERS,
)
from ..core.shipped_data import share_directory


def declare(node: Node) -> None:
    """Declare every joint_node parameter, read-only: node-wide, per joint, per muscle (by file or
    inline; a model's block only where the muscle names its ``model`` inline).
    """
    names = parameters.declare_table(node, NODE_PARAMETERS)['joints'] or []
    for joint in names:
        for muscle in (
            parameters.declare_table(node, JOINT_PARAMETERS, f'{joint}.')['muscles'] or []
        ):
            parameters.declare_table(node, MUSCLE_PARAMETERS, f'{joint}.{muscle}.')
            model_params.declare_muscle(node, f'{joint}.{muscle}.', defaults=False, read_only=True)


class JointNode(Node):
    """Thin ROS shell around one :class:`JointEngine` for all its joints."""

    def __init__(self, **kwargs) -> None:
        super().__init__('joint_node', **kwargs)
        with refusing(self):
            declare(self)
            # the overrides: also what is not declared, e.g. an inline muscle's other models
            flat = parameters.overrides(self) | parameters.values(self)
            nested = parameters.nest(flat)
            base = Path(flat.get('config_dir') or share_directory() / 'config')
            found = joints(nested, base)
            self.identification = [identification(j, nested, base) for j in found]
            settings = [
                Settings(
                    float(nested[j.name]['cocontraction']),
                    str(nested[j.name]['cocontraction_mode']),
                )
                for j in found
            ]
            self.engine = JointEngine(
                found,
                settings,
                float(flat['ambient_pressure']),
                float(flat['max_input_age']),
                hold=DIAGNOSTIC_PERIOD,
                pressure_reference=str(flat['pressure_reference']),
            )
        parameters.warn_unknown(self, model_params.expected_undeclared)  # inline muscles' models
        self._ros_clock = self.get_clock().handle
        self._torque_pub = self.create_publisher(JointState, 'torque_estimate', 10)
        self._stiffness_pub = self.create_publisher(JointState, 'stiffness_estimate', 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._command_pubs = []
        for k, joint in enumerate(found):
            pubs = []
            for m, muscle in enumerate(joint.muscle_names):
                self.create_subscription(
                    FluidPressure,
                    f'{muscle}/pressure',
                    partial(self._on_pressure, k, m),
                    INPUT_QOS,
                )
                pubs.append(self.create_publisher(FluidPressure, f'{muscle}/pressure_command', 10))
            self._command_pubs.append(pubs)
        self.create_subscription(JointState, 'joint_states', self._on_states, INPUT_QOS)
        self.create_subscription(JointState, 'torque_command', self._on_torque, 10)
        self.create_subscription(
            JointState, 'stiffness_command', partial(self._on_level, self.engine.stiffness), 10
        )
        self.create_subscription(
            JointState,
            'cocontraction_command',
            partial(self._on_level, self.engine.cocontraction),
            10,
        )
        names = [
            j.name for j in found
        ]  # prebuilt messages of every joint (the usual joint_states)
        self._all = [
            StampedTemplate(
                serialize_message(JointState(name=names, effort=sentinels(len(names)).tolist())),
                len(names),
            )
            for _ in range(2)
        ]
        self._names = names
        self.create_timer(DIAGNOSTIC_PERIOD, self.publish_status)
        self.get_logger().info(
            '; '.join(
                f"joint '{j.name}': {j.muscle_names[0]} ({j.muscles[0].model.name}) "
                f'shortens for positive angle, {j.muscle_names[1]} ({j.muscles[1].model.name})'
                for j in found
            )
        )

    def now(self) -> float:
        """The node clock (ROS time) [s], without building an rclpy Time."""
        return self._ros_clock.get_now().nanoseconds * 1e-9

    def _on_pressure(self, k: int, m: int, msg: FluidPressure) -> None:
        self.engine.pressure(k, m, msg.fluid_pressure, seconds(msg.header.stamp), self.now())

    def _on_states(self, msg: JointState) -> None:
        now, stamp = self.now(), msg.header.stamp
        t = seconds(stamp)
        names, positions = msg.name, msg.position
        done, torques, stiffnesses = [], [], []
        if len(positions) != len(names):
            for k in {self.engine.index[n] for n in names if n in self.engine.index}:
                self.engine.reject(
                    k, f'joint_states: {len(names)} names, {len(positions)} positions', now
                )
            return
        for i, name in enumerate(names):
            k = self.engine.index.get(name)
            if k is None:
                continue
            result = self.engine.angle(k, positions[i], t, now)
            if result is not None:
                done.append(name)
                torques.append(result[0])
                stiffnesses.append(result[1])
        if done == self._names:
            for pub, template, values in zip(
                (self._torque_pub, self._stiffness_pub), self._all, (torques, stiffnesses)
            ):
                template.values[:] = values
                pub.publish(template(stamp.sec, stamp.nanosec))
        elif done:
            for pub, values in ((self._torque_pub, torques), (self._stiffness_pub, stiffnesses)):
                out = JointState(name=done, effort=values)
                out.header.stamp = stamp
                pub.publish(out)

    def _on_torque(self, msg: JointState) -> None:
        now = self.now()
        for name, torque in self._entries(msg, now):
            k = self.engine.index[name]
            absolute = self.engine.command(k, torque, now)
            if absolute is not None:
                stamp = self.get_clock().now().to_msg()
                for pub, value, muscle in zip(
                    self._command_pubs[k], absolute, self.engine.joints[k].muscle_names
                ):
                    out = FluidPressure(fluid_pressure=value)
                    out.header.stamp, out.header.frame_id = stamp, muscle
                    pub.publish(out)

    def _on_level(self, apply, msg: JointState) -> None:
        now = self.now()
        for name, value in self._entries(msg, now):
            apply(self.engine.index[name], value, now)

    def _entries(self, msg: JointState, now: float) -> list[tuple[str, float]]:
        """(joint, effort) of a command's entries of this node's joints; mismatched arrays are
        rejected.
        """
        ours = [n for n in msg.name if n in self.engine.index]
        if len(msg.effort) != len(msg.name):
            for name in ours:
                self.engine.reject(
                    self.engine.index[name],
                    f'command: {len(msg.name)} names, {len(msg.effort)} efforts',
                    now,
                )
            return []
        return [(n, e) for n, e in zip(msg.name, msg.effort) if n in self.engine.index]

    def publish_status(self) -> None:
        """One DiagnosticStatus per joint in one DiagnosticArray."""
        now = self.now()
        entries = []
        for k, joint in enumerate(self.engine.joints):
            level, message, values = self.engine.status(k, now)
            entries.append(
                (
                    joint.name,
                    ' / '.join(m.spec.name for m in joint.muscles),
                    level,
                    message,
                    values | self.identification[k],
                )
            )
        self._diag_pub.publish(diagnostic_array(self, entries))


def main(args: list[str] | None = None) -> int:
    return run('joint_node', JointNode, args)


if __name__ == '__main__':
    sys.exit(main())
