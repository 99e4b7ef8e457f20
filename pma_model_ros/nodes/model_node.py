"""model_node: force estimate and pressure command of one identified pneumatic muscle.

Subscribes ``pressure`` (sensor_msgs/FluidPressure, absolute Pa), ``muscle_state``
(sensor_msgs/JointState: position = length [m], velocity = length rate [m/s]) and
``force_command`` (geometry_msgs/WrenchStamped, force.x = wanted tension [N]).
Publishes ``force_estimate`` (WrenchStamped, force.x = tension [N]),
``pressure_command`` (FluidPressure, absolute Pa) and ``/diagnostics``.
The logic lives in :mod:`pma_model_ros.core.estimator`; this node converts messages.
"""
from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from rcl_interfaces.msg import SetParametersResult
from sensor_msgs.msg import FluidPressure, JointState

from ..core.estimator import Estimate, Estimator, Level
from . import model_params
from .ros_time import now_seconds, seconds
from .startup import StartupError, run

DIAGNOSTIC_PERIOD = 1.0  # [s]; also how long a bad input or a warning holds the level up


class ModelNode(Node):
    """Thin ROS shell around :class:`Estimator`."""

    def __init__(self) -> None:
        super().__init__("model_node")
        try:
            model_params.declare(self)
            self._settings = model_params.settings(model_params.values(self))
        except (ParameterException, ValueError) as err:
            raise StartupError(str(err)) from None
        self._estimator = Estimator(self._settings.config, hold=DIAGNOSTIC_PERIOD)
        self._level: Level | None = None
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)

        self._estimate_pub = self.create_publisher(WrenchStamped, "force_estimate", 10)
        self._command_pub = self.create_publisher(FluidPressure, "pressure_command", 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(FluidPressure, "pressure", self._on_pressure, qos_profile_sensor_data)
        self.create_subscription(JointState, "muscle_state", self._on_state, qos_profile_sensor_data)
        self.create_subscription(WrenchStamped, "force_command", self._on_command, 10)
        self.create_timer(DIAGNOSTIC_PERIOD, lambda: self._publish_status(now_seconds(self)))
        model = self._settings.config.model
        self.get_logger().info(f"{model.spec.name} with model {model.model.name}, joint '{self._settings.joint_name}'")

    def _validate(self, changes: list[Parameter]) -> SetParametersResult:
        """Accept a change only if the whole would-be parameter set builds a muscle."""
        flat = model_params.values(self)
        flat.update({p.name: model_params.plain(p.value) for p in changes})
        try:
            model_params.settings(flat)
        except ValueError as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply(self, _changes: list[Parameter]) -> None:
        self._settings = model_params.settings(model_params.values(self))
        self._estimator.config = self._settings.config   # one immutable object: atomic swap

    def _on_pressure(self, msg: FluidPressure) -> None:
        now = now_seconds(self)
        pair = self._estimator.pressure(msg.fluid_pressure, seconds(msg.header.stamp), now, msg.header.stamp)
        self._publish_estimate(self._estimator.estimate(pair, now))
        self._check_level(now)

    def _on_state(self, msg: JointState) -> None:
        now = now_seconds(self)
        pair = self._estimator.joint_state(msg.name, msg.position, msg.velocity, self._settings.joint_name,
                                           seconds(msg.header.stamp), now, msg.header.stamp)
        self._publish_estimate(self._estimator.estimate(pair, now))
        self._check_level(now)

    def _on_command(self, msg: WrenchStamped) -> None:
        now = now_seconds(self)
        command = self._estimator.command(msg.wrench.force.x, now)
        if command is not None:
            out = FluidPressure(fluid_pressure=command.pressure)
            out.header.stamp = self.get_clock().now().to_msg()
            out.header.frame_id = self._settings.frame_id
            self._command_pub.publish(out)
        self._check_level(now)

    def _publish_estimate(self, estimate: Estimate | None) -> None:
        if estimate is None:
            return
        msg = WrenchStamped()
        msg.header.stamp = estimate.tag
        msg.header.frame_id = self._settings.frame_id
        msg.wrench.force.x = estimate.force
        self._estimate_pub.publish(msg)

    def _check_level(self, now: float) -> None:
        if self._estimator.level(now)[0] != self._level:
            self._publish_status(now)

    def _publish_status(self, now: float) -> None:
        status = self._estimator.status(now)
        self._level = status.level
        spec = self._settings.config.model.spec
        msg = DiagnosticArray(status=[DiagnosticStatus(
            level=bytes([status.level]), name=f"{self.get_fully_qualified_name()}: {self._settings.joint_name}",
            message=status.message, hardware_id=spec.name,
            values=[KeyValue(key=k, value=v) for k, v in status.values.items()])])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run("model_node", ModelNode, args)


if __name__ == "__main__":
    sys.exit(main())
