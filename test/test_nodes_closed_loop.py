"""Closed loop: force_command -> model_node -> pressure_command -> simulator -> measured force.

The simulator holds 0.23 m and follows the pressure command with a 0.05 s time
constant.  At 0.23 m the map's muscle reaches about 244 N at its highest measured
pressure (650 kPa), so 300 N is out of reach there; the commands are 50, 150, 230 N.
"""

import math

from geometry_msgs.msg import WrenchStamped
import pytest
from sensor_msgs.msg import FluidPressure

from conftest import CONFIGS
from node_messages import AMBIENT, force_command, SENSOR_QOS
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map

pytestmark = pytest.mark.ros

LENGTH = 0.23  # [m]
TIME_CONSTANT = 0.05  # [s]
TOLERANCE = 5.0  # steady-state error [% of the map's max force]


def test_force_commands_reach_steady_state(ros, processes, namespace):
    model = muscle_model(read_parameters(CONFIGS['DMSP-10-250']))
    max_force = shipped_force_map('DMSP-10-250').max_force
    sim = processes.node(
        'simulator_node',
        namespace,
        trajectory='constant',
        length=LENGTH,
        pressure_time_constant=TIME_CONSTANT,
    )
    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'])
    why = lambda: processes.output(sim) + processes.output(node)  # noqa: E731
    forces = ros.collect(WrenchStamped, f'{namespace}/force', SENSOR_QOS)
    commands = ros.collect(FluidPressure, f'{namespace}/pressure_command')
    publisher = ros.node.create_publisher(WrenchStamped, f'{namespace}/force_command', 10)

    for wanted in (50.0, 150.0, 230.0):
        expected = float(model.pressure(wanted, LENGTH).pressure) + AMBIENT
        arrived: list[float] = []  # node-clock time [s] the matching pressure command arrived

        def steady() -> bool:
            now = ros.now().nanoseconds * 1e-9
            if (
                not arrived
                and commands
                and math.isclose(commands[-1].fluid_pressure, expected, abs_tol=1.0)
            ):
                arrived.append(now)
            recent = [f.wrench.force.x for f in forces[-20:]]
            return (
                bool(arrived)
                and len(recent) == 20
                and now - arrived[0] > 10 * TIME_CONSTANT
                and max(recent) - min(recent) < 0.5
            )

        ros.spin_until(
            steady,
            30,
            f'a steady force after commanding {wanted} N',
            every=lambda: publisher.publish(force_command(wanted)),
            diagnose=why,
        )
        measured = sum(f.wrench.force.x for f in forces[-20:]) / 20
        assert abs(measured - wanted) <= TOLERANCE / 100 * max_force, (
            f'commanded {wanted} N, measured {measured:.1f} N (tolerance {TOLERANCE} % of '
            f'{max_force} N)'
        )
