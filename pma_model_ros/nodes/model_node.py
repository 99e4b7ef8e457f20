"""model_node: force estimates and pressure commands of one or many identified pneumatic muscles.

One muscle (parameters at the top level): subscribes ``pressure`` (sensor_msgs/FluidPressure,
absolute Pa), ``muscle_state`` (sensor_msgs/JointState: position = length [m], velocity =
length rate [m/s]) and ``force_command`` (geometry_msgs/WrenchStamped, force.x = wanted
tension [N]); publishes ``force_estimate`` (WrenchStamped, force.x = tension [N]),
``pressure_command`` (FluidPressure, absolute Pa) and ``/diagnostics``.

Many muscles (``muscles: [a, b, ...]``, each one's parameters under ``<name>.``): the same
topics under ``<name>/`` (``input_mode: per_muscle``, :class:`MuscleTopics`), or
(``input_mode: combined``, :class:`CombinedTopics`) one ``muscle_states`` JointState with every
length, one ``muscle_pressures`` JointState with every absolute pressure [Pa] in ``position``,
answered by one ``force_estimates`` JointState (effort = tension [N]); commands come in one
``force_commands`` JointState (effort = wanted tension [N]) and go out in one ``pressure_commands``
JointState (position = absolute pressure [Pa]).  Every decision is the
:class:`~pma_model_ros.core.engine.Engine`'s; the two adapters only turn messages into its calls.
"""

from __future__ import annotations

from functools import partial
import sys
from typing import Sequence

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3, Wrench, WrenchStamped
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Header

from . import model_params
from .diagnostics import diagnostic_array
from .parameters import warn_unknown
from .startup import refusing, run
from ..core.cdr import sentinels, StampedTemplate
from ..core.engine import CombinedInputs, Engine, REPORT_INTERVAL_PER_MUSCLE, seconds
from ..core.param_file import NodeSettings

DIAGNOSTIC_PERIOD = 1.0  # [s]; also how long a bad input or a warning holds the level up

#: Inputs: sensor-data QoS (best effort, volatile) with a queue of 100 instead of 5 (0.1 s at 1
#: kHz): a briefly stalled node catches up, and inputs older than max_input_age are counted stale
#: (ERROR), instead of being dropped unseen.
INPUT_QOS = QoSProfile(
    depth=100,
    reliability=qos_profile_sensor_data.reliability,
    durability=qos_profile_sensor_data.durability,
    history=qos_profile_sensor_data.history,
)


class ModelNode(Node):
    """Thin ROS shell around one :class:`Engine` for all its muscles; topics by the input mode's
    adapter.
    """

    def __init__(self, **kwargs) -> None:
        super().__init__('model_node', **kwargs)
        with refusing(self):
            self._names, mode = model_params.declare(self)
            self._blocks = model_params.ModelBlocks(self, self._names)
            flat = self._blocks.would_be([])
            self.settings = model_params.all_settings(flat, self._names)
            self.identification = model_params.identifications(flat, self._names)
            self.engine = Engine(
                [s.config for s in self.settings],
                hold=DIAGNOSTIC_PERIOD,
                report_interval=REPORT_INTERVAL_PER_MUSCLE * len(self.settings),
                **model_params.pairing(flat),
            )
        warn_unknown(self, model_params.expected_undeclared)
        self.add_pre_set_parameters_callback(self._blocks.hold)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._ros_clock = self.get_clock().handle  # see now()
        self.topics = (CombinedTopics if mode == 'combined' else MuscleTopics)(self, self._names)
        self.create_timer(DIAGNOSTIC_PERIOD, lambda: self.publish_status(self.now()))
        muscles = [
            f'{s.config.model.spec.name} with model {s.config.model.model.name}, joint '
            f"'{s.joint_name}'"
            for s in self.settings
        ]
        self.get_logger().info(
            muscles[0]
            if not self._names
            else f'{len(muscles)} muscles, {mode}: ' + '; '.join(muscles)
        )

    def now(self) -> float:
        """The node clock (ROS time; sim time with use_sim_time) [s], read without building an
        rclpy Time.
        """
        return self._ros_clock.get_now().nanoseconds * 1e-9

    def _validate(self, changes: list[Parameter]) -> SetParametersResult:
        """Accept a change only if the whole would-be parameter set builds every muscle."""
        if not self._blocks.swapping:
            try:
                model_params.all_settings(self._blocks.would_be(changes), self._names)
            except ValueError as err:
                return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply(self, _changes: list[Parameter]) -> None:
        if self._blocks.swapping:
            return
        flat = self._blocks.applied()
        settings = model_params.all_settings(flat, self._names)
        self.engine.configure([s.config for s in settings])
        self.settings = settings
        self.identification = model_params.identifications(flat, self._names)
        self.topics.use(settings)

    def check_status(self, now: float, k: int | None = None) -> None:
        """Publish the diagnostics at once if a level (muscle ``k``'s, or any) changed since the
        last report.
        """
        if self.engine.status_due(now, k):
            self.publish_status(now)

    def publish_status(self, now: float) -> None:
        """One DiagnosticStatus per muscle in one DiagnosticArray."""
        entries = []
        for k, s in enumerate(self.settings):
            status = self.engine.status(k, now)
            entries.append(
                (
                    s.joint_name,
                    s.config.model.spec.name,
                    status.level,
                    status.message,
                    status.values | self.identification[k],
                )
            )
        self._diag_pub.publish(diagnostic_array(self, entries))


class MuscleTopics:
    """``pressure``, ``muscle_state``, ``force_command`` in and ``force_estimate``,
    ``pressure_command`` out, per muscle (under ``<name>/`` with several): each message is one call
    of the engine's one-muscle path.
    """

    def __init__(self, node: ModelNode, names: Sequence[str]) -> None:
        self.node, self.engine = node, node.engine
        prefixes = [f'{name}/' for name in names] or ['']
        self._estimate_pubs = [
            node.create_publisher(WrenchStamped, f'{p}force_estimate', 10) for p in prefixes
        ]
        self._command_pubs = [
            node.create_publisher(FluidPressure, f'{p}pressure_command', 10) for p in prefixes
        ]
        for k, prefix in enumerate(prefixes):
            node.create_subscription(
                FluidPressure, f'{prefix}pressure', partial(self._on_pressure, k), INPUT_QOS
            )
            node.create_subscription(
                JointState, f'{prefix}muscle_state', partial(self._on_state, k), INPUT_QOS
            )
            node.create_subscription(
                WrenchStamped, f'{prefix}force_command', partial(self._on_command, k), 10
            )
        self.use(node.settings)

    def use(self, settings: list[NodeSettings]) -> None:
        self._joints = [s.joint_name for s in settings]
        self._estimates = [
            StampedTemplate(
                serialize_message(
                    WrenchStamped(
                        header=Header(frame_id=s.frame_id),
                        wrench=Wrench(force=Vector3(x=sentinels(1)[0])),
                    )
                ),
                1,
            )
            for s in settings
        ]

    def _on_pressure(self, k: int, msg: FluidPressure) -> None:
        now, stamp = self.node.now(), msg.header.stamp
        force = self.engine.pressure(k, msg.fluid_pressure, seconds(stamp), now, stamp)
        self._answer(k, force, now)

    def _on_state(self, k: int, msg: JointState) -> None:
        now, stamp = self.node.now(), msg.header.stamp
        force = self.engine.joint_state(
            k, msg.name, msg.position, msg.velocity, self._joints[k], seconds(stamp), now, stamp
        )
        self._answer(k, force, now)

    def _answer(self, k: int, force: float | None, now: float) -> None:
        if force is not None:
            estimate, tag = self._estimates[k], self.engine.tag
            estimate.values[0] = force
            self._estimate_pubs[k].publish(estimate(tag.sec, tag.nanosec))
        self.node.check_status(now, k)

    def _on_command(self, k: int, msg: WrenchStamped) -> None:
        now = self.node.now()
        pressure = self.engine.command(k, msg.wrench.force.x, now)
        if pressure is not None:
            out = FluidPressure(fluid_pressure=pressure)
            out.header.stamp = self.node.get_clock().now().to_msg()
            out.header.frame_id = self.node.settings[k].frame_id
            self._command_pubs[k].publish(out)
        self.node.check_status(now, k)


class CombinedTopics:
    """``muscle_pressures``, ``muscle_states``, ``force_commands`` in and ``force_estimates``,
    ``pressure_commands`` out, each a JointState of every muscle: each message is one vectorised
    call of the engine.
    """

    def __init__(self, node: ModelNode, names: Sequence[str]) -> None:
        self.node, self.engine = node, node.engine
        self._states_pub = node.create_publisher(JointState, 'force_estimates', 10)
        self._commands_pub = node.create_publisher(JointState, 'pressure_commands', 10)
        node.create_subscription(JointState, 'muscle_pressures', self._on_pressures, INPUT_QOS)
        node.create_subscription(JointState, 'muscle_states', self._on_states, INPUT_QOS)
        node.create_subscription(JointState, 'force_commands', self._on_commands, 10)
        self.use(node.settings)

    def use(self, settings: list[NodeSettings]) -> None:
        self._inputs = CombinedInputs(self.engine, [s.joint_name for s in settings])
        n = len(settings)  # a message of every muscle's estimate
        self._all = StampedTemplate(
            serialize_message(JointState(name=self._inputs.joints, effort=sentinels(n).tolist())),
            n,
        )

    def _on_pressures(self, msg: JointState) -> None:
        now = self.node.now()
        self._answer(self._inputs.pressures(msg.name, msg.position, msg.header.stamp, now), now)

    def _on_states(self, msg: JointState) -> None:
        now = self.node.now()
        self._answer(
            self._inputs.lengths(msg.name, msg.position, msg.velocity, msg.header.stamp, now), now
        )

    def _answer(self, estimated: np.ndarray, now: float) -> None:
        """One force_estimates of the muscles that got an estimate (the prebuilt message when all
        did).
        """
        if estimated.all():
            tag = self.engine.newest_tag(estimated)
            self._all.values[:] = self.engine.forces
            self._states_pub.publish(self._all(tag.sec, tag.nanosec))
        elif estimated.any():
            msg = JointState(
                name=[j for j, e in zip(self._inputs.joints, estimated.tolist()) if e],
                effort=self.engine.forces[estimated].tolist(),
            )
            msg.header.stamp = self.engine.newest_tag(estimated)
            self._states_pub.publish(msg)
        self.node.check_status(now)

    def _on_commands(self, msg: JointState) -> None:
        """Pressure commands of the muscles named in ``msg`` (the others are not commanded)."""
        now = self.node.now()
        joints, pressures = self._inputs.commands(msg.name, msg.effort, now)
        if joints:
            out = JointState(name=joints, position=pressures)
            out.header.stamp = self.node.get_clock().now().to_msg()
            self._commands_pub.publish(out)
        self.node.check_status(now)


def main(args: list[str] | None = None) -> int:
    return run('model_node', ModelNode, args)


if __name__ == '__main__':
    sys.exit(main())
