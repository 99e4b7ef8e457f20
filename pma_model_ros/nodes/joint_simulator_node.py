"""joint_simulator_node: an antagonistic joint of two muscles whose forces are their measured force
maps.

Publishes, at ``rate``, ``joint_states`` (sensor_msgs/JointState: position θ [rad], velocity
[rad/s], effort = the measured-map torque [N·m]) and each muscle's ``<muscle>/pressure``
(sensor_msgs/FluidPressure, absolute Pa), all with the same stamp.  Each muscle's pressure follows
``<muscle>/pressure_command`` (FluidPressure, absolute Pa) with first-order dynamics.  ``mode:
held``: the angle moves only to the position of an ``angle_command`` (JointState, the joint's
entry), as on a test bench; ``mode: link``: a link with inertia and damping.  Parameters are read
at start-up; the physics is
:mod:`pma_model_ros.core.simulation.joint`.
"""

from __future__ import annotations

from functools import partial
import sys

from rclpy.node import Node
from sensor_msgs.msg import FluidPressure, JointState

from .parameters import declare_table, warn_unknown
from .qos import publisher, RELIABLE, SENSOR_OUTPUT, subscription, warn_unknown_overrides
from .rclpy_private import parameter_overrides
from .ros_time import now_seconds
from .startup import refusing, run
from ..core.simulation.joint import PARAMETERS, SimulatedJoint


class JointSimulatorNode(Node):
    """Publishes a simulated antagonistic joint at a fixed rate."""

    def __init__(self, **kwargs) -> None:
        super().__init__('joint_simulator_node', **kwargs)
        with refusing(self):
            p = declare_table(self, PARAMETERS)
            self.joint = SimulatedJoint(p, now_seconds(self))
        warn_unknown(self)
        self._name = str(p['joint_name'])
        self._state_pub = publisher(self, JointState, 'joint_states', SENSOR_OUTPUT)
        self._pressure_pubs = [
            publisher(self, FluidPressure, f'{m}/pressure', SENSOR_OUTPUT) for m in p['muscles']
        ]
        for k, muscle in enumerate(p['muscles']):
            callback = partial(self._on_command, k)
            subscription(self, FluidPressure, f'{muscle}/pressure_command', callback, RELIABLE)
        subscription(self, JointState, 'angle_command', self._on_angle, RELIABLE)
        warn_unknown_overrides(self, parameter_overrides(self))
        self.create_timer(1.0 / p['rate'], self._tick)
        self.get_logger().info(
            f"simulating joint '{self._name}' ({p['mode']}) of {p['maps'][0]} and "
            f'{p["maps"][1]} at {p["rate"]:g} Hz'
        )

    def _on_command(self, k: int, msg: FluidPressure) -> None:
        self.joint.command(k, msg.fluid_pressure)

    def _on_angle(self, msg: JointState) -> None:
        if self._name in msg.name and len(msg.position) == len(msg.name):
            self.joint.hold(msg.position[list(msg.name).index(self._name)])

    def _tick(self) -> None:
        now = self.get_clock().now()
        torque = self.joint.step(now.nanoseconds * 1e-9)
        stamp = now.to_msg()
        state = JointState(
            name=[self._name],
            position=[self.joint.angle],
            velocity=[self.joint.velocity],
            effort=[torque],
        )
        state.header.stamp = stamp
        self._state_pub.publish(state)
        ambient = float(self.joint.params['ambient_pressure'])
        for pub, gauge in zip(self._pressure_pubs, self.joint.pressures):
            msg = FluidPressure(fluid_pressure=gauge + ambient)
            msg.header.stamp = stamp
            pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run('joint_simulator_node', JointSimulatorNode, args)


if __name__ == '__main__':
    sys.exit(main())
