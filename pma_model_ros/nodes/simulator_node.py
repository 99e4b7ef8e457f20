"""simulator_node: a pneumatic muscle whose static force is a measured force map.

The truth is a shipped map (``muscle``), a user's map CSV with its spec (``map_file``,
``spec_file``) or an identified muscle (``params_file``), optionally drifting (``drift.*``).

Publishes, at ``rate``, ``pressure`` (sensor_msgs/FluidPressure, absolute Pa),
``muscle_state`` (sensor_msgs/JointState: position = length [m], velocity = length
rate [m/s], effort = measured tension [N]) and ``force`` (geometry_msgs/WrenchStamped,
force.x = measured tension [N]), all with the same stamp.  The pressure follows
``pressure_command`` (FluidPressure, absolute Pa) with first-order dynamics.
Parameters are read at start-up; the physics is :mod:`pma_model_ros.core.simulation.muscle`.

``simulator_node --record OUT [--storage mcap|sqlite3] --ros-args ...`` also writes
what it publishes to a new rosbag2 bag OUT (log time = the stamp; storage from
``--storage``, else OUT's suffix ``.mcap``/``.db3``, else mcap), finished on Ctrl-C.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.serialization import serialize_message
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import FluidPressure, JointState

from .parameters import declare_table, warn_unknown
from .qos import publisher, RELIABLE, SENSOR_OUTPUT, subscription, warn_unknown_overrides
from .rclpy_private import parameter_overrides
from .ros_time import now_seconds
from .startup import refusing, run
from ..core.files.node_parameters import frame_of
from ..core.simulation.muscle import PARAMETERS, SimulatedMuscle


class SimulatorNode(Node):
    """Publishes a simulated muscle at a fixed rate."""

    def __init__(self, record: str | None = None, storage: str | None = None, **kwargs) -> None:
        super().__init__('simulator_node', **kwargs)
        with refusing(self):
            p = declare_table(self, PARAMETERS)
            self._muscle = SimulatedMuscle(p, now_seconds(self))
        self._frame = frame_of(self._muscle.joint)  # model_node's default frame of the muscle
        warn_unknown(self)
        self._pressure_pub = publisher(self, FluidPressure, 'pressure', SENSOR_OUTPUT)
        self._state_pub = publisher(self, JointState, 'muscle_state', SENSOR_OUTPUT)
        self._force_pub = publisher(self, WrenchStamped, 'force', SENSOR_OUTPUT)
        self._ticks = 0
        with refusing(self):
            self._recorder = self._open_record(record, storage) if record else None
        subscription(self, FluidPressure, 'pressure_command', self._on_command, RELIABLE)
        warn_unknown_overrides(self, parameter_overrides(self))
        self.create_timer(1.0 / p['rate'], self._tick)
        self.get_logger().info(
            f'simulating {self._muscle.name} ({p["trajectory"]}) at {p["rate"]:g} Hz'
            + (f', recording to {record}' if record else '')
        )

    def _open_record(self, out: str, storage: str | None):
        """A bag writer with this node's three topics (rosbags is needed only when recording)."""
        from ..bags.bag_io import BagWriter, SENSOR_DATA

        try:
            writer = BagWriter(out, storage)
        except ValueError as err:
            raise ValueError(f'--record: {err}') from None
        types = {
            self._pressure_pub: 'sensor_msgs/msg/FluidPressure',
            self._state_pub: 'sensor_msgs/msg/JointState',
            self._force_pub: 'geometry_msgs/msg/WrenchStamped',
        }
        return writer, {
            pub: writer.topic(pub.topic_name, msgtype, [SENSOR_DATA])
            for pub, msgtype in types.items()
        }

    def _on_command(self, msg: FluidPressure) -> None:
        self._muscle.command(msg.fluid_pressure)

    def _tick(self) -> None:
        self._ticks += 1
        now = self.get_clock().now()
        r = self._muscle.run([now.nanoseconds * 1e-9])
        measured = float(r.force[0])
        joint = self._muscle.joint
        pressure = FluidPressure(fluid_pressure=float(r.pressure[0]))
        state = JointState(
            name=[joint],
            position=[float(r.length[0])],
            velocity=[float(r.rate[0])],
            effort=[measured],
        )
        wrench = WrenchStamped()
        wrench.wrench.force.x = measured
        stamp = now.to_msg()
        for pub, msg in (
            (self._pressure_pub, pressure),
            (self._state_pub, state),
            (self._force_pub, wrench),
        ):
            msg.header.stamp = stamp
            msg.header.frame_id = self._frame
            pub.publish(msg)
            if self._recorder is not None:
                writer, topics = self._recorder
                writer.write_raw(topics[pub], now.nanoseconds, serialize_message(msg))

    def finish_recording(self) -> None:
        """Finish the recording (renamed to its path only now; dropped if it holds nothing)."""
        if self._recorder is not None:
            writer, self._recorder = self._recorder[0], None
            if self._ticks:
                writer.close()
            else:
                writer.abort()


def main(args: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='simulator_node',
        description='simulated pneumatic muscle (ROS 2 node)',
        epilog='ROS arguments follow --ros-args, e.g. -p rate:=1000.0',
    )
    parser.add_argument(
        '--record', metavar='OUT', help='also write what is published to a new bag OUT'
    )
    parser.add_argument(
        '--storage',
        choices=('mcap', 'sqlite3'),
        help="storage of the bag (default: OUT's suffix, else mcap)",
    )
    argv = sys.argv if args is None else args
    options = parser.parse_args(remove_ros_args(argv)[1:])
    if options.record and (Path(options.record).exists() or Path(options.record).is_symlink()):
        print(
            f'simulator_node: error: --record {options.record}: exists; not overwriting it '
            '(remove it or record to another name)',
            file=sys.stderr,
        )
        return 1
    nodes: list[SimulatorNode] = []

    def make() -> SimulatorNode:
        nodes.append(SimulatorNode(options.record, options.storage))
        return nodes[-1]

    code = run('simulator_node', make, argv)
    for node in nodes:  # after rclpy's shutdown (closing sqlite3 beside it crashed)
        node.finish_recording()
    return code


if __name__ == '__main__':
    sys.exit(main())
