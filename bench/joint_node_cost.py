"""Per-message CPU cost of joint_node's callbacks, in-process (no DDS).

Is a 4-DOF arm at 1 kHz affordable?

Usage: ``scripts/netns-run .venv/bin/python bench/joint_node_cost.py [--quick] [--joints N]
[--repeat R]`` (or ``bench/run joint_node_cost``; ``--quick``: R = 200).  Not a test: it prints a
table.  Builds a JointNode on a private rclpy context from N copies of the example elbow
(config/example_joint.yaml), then times, with :func:`time.process_time` over R calls each (best of
5): one joint_states message of all N joints (the estimates of every joint, both published), one
muscle pressure, one torque command (lower-pressure co-contraction: closed form) and one with a
wanted stiffness (brentq).  The last line is the CPU share at 1 kHz of one joint_states plus 2 N
pressures per millisecond.
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path
import tempfile
import time

import rclpy
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, JointState
import yaml

from pma_model_ros.core.files.param_file import read_parameters
from pma_model_ros.nodes.joint_node import JointNode

REPO = Path(__file__).resolve().parents[1]
AMBIENT = 101325.0


def arm(path: Path, n: int) -> None:
    elbow = read_parameters(REPO / 'config' / 'example_joint.yaml')['elbow']
    joints = {}
    for k in range(n):
        block = {
            key: copy.deepcopy(v) for key, v in elbow.items() if key not in ('flexor', 'extensor')
        }
        block |= {
            'muscles': [f'j{k}_flexor', f'j{k}_extensor'],
            'positive': f'j{k}_flexor',
            f'j{k}_flexor': dict(elbow['flexor']),
            f'j{k}_extensor': dict(elbow['extensor']),
        }
        joints[f'j{k}'] = block
    path.write_text(
        yaml.safe_dump({'/**': {'ros__parameters': {'joints': list(joints), **joints}}})
    )


def best(call, repeat: int) -> float:
    """Best of 5 runs of ``repeat`` calls: CPU seconds per call."""
    runs = []
    for _ in range(5):
        start = time.process_time()
        for _ in range(repeat):
            call()
        runs.append((time.process_time() - start) / repeat)
    return min(runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--joints', type=int, default=4)
    parser.add_argument('--repeat', type=int, default=2000)
    parser.add_argument('--quick', action='store_true', help='200 calls per run')
    args = parser.parse_args()
    if args.quick:
        args.repeat = 200
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'arm.yaml'
        arm(path, args.joints)
        context = rclpy.Context()
        rclpy.init(context=context, args=['--ros-args', '--params-file', str(path)])
        node = JointNode(
            context=context,
            parameter_overrides=[Parameter('config_dir', value=str(REPO / 'config'))],
        )
    try:
        stamp = node.get_clock().now().to_msg()
        msg = FluidPressure(fluid_pressure=AMBIENT + 400e3)
        msg.header.stamp = stamp
        p = serialize_message(msg)  # raw subscriptions: callbacks take bytes
        for k in range(args.joints):
            node._on_pressure(k, 0, p)
            node._on_pressure(k, 1, p)
        names = [j.name for j in node.engine.joints]
        states = JointState(
            name=names,
            position=[0.1 * (k % 5) for k in range(args.joints)],
            velocity=[0.0] * args.joints,
        )
        node.now = lambda: stamp.sec * 10**9 + stamp.nanosec  # inputs stay fresh [ns]
        states.header.stamp = stamp
        states = serialize_message(states)
        torque = serialize_message(JointState(name=[names[0]], effort=[1.0]))
        rows = {
            'joint_states, all joints': best(lambda: node._on_states(states), args.repeat),
            'one pressure': best(lambda: node._on_pressure(0, 0, p), args.repeat),
            'torque command, co-contraction': best(
                lambda: node._on_torque(torque), args.repeat // 4
            ),
        }
        node.engine.stiffness(0, 4.5, node.now())
        rows['torque command, stiffness'] = best(
            lambda: node._on_torque(torque), args.repeat // 20
        )
        print(f'{args.joints} joints, CPU time per message (best of 5 x {args.repeat}):')
        for name, seconds in rows.items():
            print(f'  {name:<32}{seconds * 1e6:8.1f} us')
        cycle = rows['joint_states, all joints'] + 2 * args.joints * rows['one pressure']
        print(
            f'1 kHz of joint_states + {2 * args.joints} pressures: {cycle * 1e6:.0f} us per ms = '
            f'{cycle * 1e3 * 100:.0f} % of a core'
        )
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)


if __name__ == '__main__':
    main()
