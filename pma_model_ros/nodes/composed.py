"""pma_composed: model_node and joint_node (and, for tests, the simulators) in one process, spun by
one executor, from one parameter file.

rclpy has no components; this executable stands in for a component container::

    pma_composed [--nodes model_node joint_node ...] --ros-args
        --params-file composed.yaml [-r model_node:__ns:=/left_biceps] [-r __ns:=/robot]

The parameter file holds each node's section under its name, as ROS parameter files hold several
nodes: ``/**/model_node:`` and ``/**/joint_node:`` (``/**/``: in any namespace; or the fully
qualified name, e.g. ``/left_biceps/model_node``), each with its ``ros__parameters`` as in the
node's own file, and ``/**:`` for what every node reads (``use_sim_time``, ``executor``).
``config/example_composed.yaml`` is the DMSP-10-250 of ``config/dmsp_10_250.yaml`` (martens) and
the elbow of ``config/example_joint.yaml``.  Node-specific remapping rules (``<node>:``) come
before global ones (rcl applies the first that matches).

Each node is built as its own executable builds it (``autostart``: configured and activated, each
a managed node with its own lifecycle services); a bad parameter of any node ends the process with
one FATAL line and exit code 1 (:func:`~.startup.run`), and the nodes' ``executor`` parameters must
name the same executor.
"""

from __future__ import annotations

import argparse
import sys

from rclpy.utilities import remove_ros_args

from .joint_node import JointNode
from .joint_simulator_node import JointSimulatorNode
from .model_node import ModelNode
from .simulator_node import SimulatorNode
from .startup import run

#: The nodes this executable can run, by node name.
NODES = {
    'model_node': ModelNode,
    'joint_node': JointNode,
    'simulator_node': SimulatorNode,
    'joint_simulator_node': JointSimulatorNode,
}


def main(args: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='pma_composed',
        description='model_node and joint_node (and the simulators) in one process and executor',
        epilog='ROS arguments follow --ros-args, e.g. --params-file config/example_composed.yaml',
    )
    parser.add_argument(
        '--nodes',
        nargs='+',
        choices=NODES,
        default=['model_node', 'joint_node'],
        help='the nodes to run, in this order (default: model_node joint_node)',
    )
    argv = sys.argv if args is None else args
    options = parser.parse_args(remove_ros_args(argv)[1:])
    if len(set(options.nodes)) != len(options.nodes):
        parser.error(f'--nodes: a node named twice in {options.nodes}')
    return run('pma_composed', [NODES[name] for name in options.nodes], argv)


if __name__ == '__main__':
    sys.exit(main())
