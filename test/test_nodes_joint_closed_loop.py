"""Closed loop over DDS: torque_command -> joint_node -> pressure_command -> simulated joint -> map
torque.

The simulated joint (joint_simulator_node, held angle) has the example joint's pulley (15 mm) and
lengths (0.234 m at 0 rad) and two DMSP-10-250 whose forces are the measured map (Table A2);
joint_node uses the example file's identified models.  The map was measured up to 650 kPa, so the
wanted torques span the range the map reaches at the file's co-contraction (lower pressure 300
kPa), 5 % to 95 % of it.  "Max torque at an angle" is the map's: flexor at 650 kPa, extensor
unpressurised (or the reverse, whichever is larger).
"""

import math

import pytest
from sensor_msgs.msg import FluidPressure, JointState

from conftest import REPO
from node_messages import SENSOR_QOS
from pma_model_ros.core.simulation.joint import PARAMETERS, SimulatedJoint

pytestmark = pytest.mark.ros

EXAMPLE = REPO / 'config' / 'example_joint.yaml'
TIME_CONSTANT = 0.05  # [s] of the simulated pressures
LEVEL = 300e3  # [Pa] the file's co-contraction (lower pressure)
MAP_TOP = 650e3  # [Pa] highest measured pressure
TORQUE_TOLERANCE = 5.0  # [% of the max torque at the angle]
STIFFNESS_TOLERANCE = 15.0  # [%]


def map_torque(theta, p0, p1):
    """Torque [N·m] of the measured map at ``theta`` [rad] and gauge pressures [Pa] (the
    simulator's truth).
    """
    sim = SimulatedJoint({p.name: p.default for p in PARAMETERS}, 0.0)
    sim.angle, sim.pressures = theta, [p0, p1]
    return sim.torque()


def start(processes, namespace):
    sim = processes.node('joint_simulator_node', namespace, pressure_time_constant=TIME_CONSTANT)
    node = processes.node('joint_node', namespace, EXAMPLE, config_dir=str(REPO / 'config'))
    return lambda: processes.output(sim) + processes.output(node)  # noqa: E731


class Bench:
    """The test's side of the loop: the simulated joint's states, commands to both nodes."""

    def __init__(self, ros, namespace, why):
        self.ros, self.why = ros, why
        self.states = ros.collect(JointState, f'{namespace}/joint_states', SENSOR_QOS)
        self.commands = ros.collect(FluidPressure, f'{namespace}/flexor/pressure_command')
        self._pubs = {
            name: ros.node.create_publisher(JointState, f'{namespace}/{name}', 10)
            for name in ('angle_command', 'torque_command', 'stiffness_command')
        }

    def send(self, topic, **fields):
        self._pubs[topic].publish(JointState(name=['elbow'], **fields))

    def hold(self, theta):
        self.ros.spin_until(
            lambda: self.states and self.states[-1].position[0] == theta,
            20,
            f'the joint held at {theta} rad',
            every=lambda: self.send('angle_command', position=[theta]),
            diagnose=self.why,
        )

    def steady_torque(self, what, every=None):
        """The mean of 20 simulated torques once a new pressure command arrived and settled."""
        before = len(self.commands)
        arrived = []

        def steady():
            now = self.ros.now().nanoseconds * 1e-9
            if not arrived and len(self.commands) > before:
                arrived.append(now)
            recent = [s.effort[0] for s in self.states[-20:]]
            return (
                bool(arrived)
                and now - arrived[0] > 10 * TIME_CONSTANT
                and max(recent) - min(recent) < 1e-3
            )

        self.ros.spin_until(steady, 20, what, every=every, diagnose=self.why)
        return sum(s.effort[0] for s in self.states[-20:]) / 20


@pytest.mark.parametrize('theta', [-0.5, 0.0, 0.5])
def test_torque_commands_reach_the_map_torque(ros, processes, namespace, theta):
    bench = Bench(ros, namespace, start(processes, namespace))
    bench.hold(theta)
    low, high = map_torque(theta, LEVEL, MAP_TOP), map_torque(theta, MAP_TOP, LEVEL)
    max_torque = max(map_torque(theta, MAP_TOP, 0.0), -map_torque(theta, 0.0, MAP_TOP))
    for share in (0.05, 0.275, 0.5, 0.725, 0.95):
        wanted = low + share * (high - low)
        measured = bench.steady_torque(
            f'a steady torque after commanding {wanted:.3f} N·m at {theta} rad',
            every=lambda: bench.send('torque_command', effort=[wanted]),
        )
        print(  # pytest -s
            f'{theta:+.1f} rad: wanted {wanted:+.3f} N·m, map torque {measured:+.3f} N·m, '
            f'error {100 * (measured - wanted) / max_torque:+.2f} % of {max_torque:.3f} N·m'
        )
        assert abs(measured - wanted) <= TORQUE_TOLERANCE / 100 * max_torque, (
            f'{theta} rad: wanted {wanted:.3f} N·m, map torque {measured:.3f} N·m (max '
            f'{max_torque:.3f} N·m)'
        )


def test_stiffness_command_gives_the_measured_stiffness(ros, processes, namespace):
    """At 0.5 rad, 0 N·m and 4.5 N·m/rad; then the held angle steps ±0.02 rad with the pressures
    kept.
    """
    theta, step, wanted = 0.5, 0.02, 4.5
    bench = Bench(ros, namespace, start(processes, namespace))
    bench.hold(theta)

    def command():
        bench.send('stiffness_command', effort=[wanted])
        bench.send('torque_command', effort=[0.0])

    at_theta = bench.steady_torque('a steady torque after the stiffness command', every=command)
    assert abs(at_theta) <= TORQUE_TOLERANCE / 100 * max(
        map_torque(theta, MAP_TOP, 0.0), -map_torque(theta, 0.0, MAP_TOP)
    )
    torques = []
    for angle in (theta + step, theta - step):
        bench.hold(angle)
        count = len(bench.states)
        ros.spin_until(
            lambda: len(bench.states) >= count + 20,
            10,
            'states at the stepped angle',
            diagnose=bench.why,
        )
        torques.append(sum(s.effort[0] for s in bench.states[-20:]) / 20)
    measured = -(torques[0] - torques[1]) / (2 * step)
    print(
        f'stiffness: wanted {wanted} N·m/rad, measured {measured:.3f} N·m/rad, torque '
        f'{at_theta:+.4f} N·m'
    )
    assert math.isclose(measured, wanted, rel_tol=STIFFNESS_TOLERANCE / 100), (
        f'wanted {wanted} N·m/rad, measured {measured:.3f} N·m/rad'
    )
