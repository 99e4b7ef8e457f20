"""``pma-model joint torque|pressures|envelope``: an antagonistic joint of a joint file."""

from __future__ import annotations

import argparse
import math

import numpy as np

from .checks import CliError, finite, gauge_pressure
from ..core.files.param_file import read_parameters
from ..core.physics.flags import describe


def _joint(args: argparse.Namespace):
    """The joint of ``--config`` named by ``--joint`` (default: the file's only joint)."""
    from ..core.files.joint_file import load_joints

    joints = {j.name: j for j in load_joints(args.config)}
    name = args.joint or (next(iter(joints)) if len(joints) == 1 else None)
    if name not in joints:
        raise CliError(f'--joint: choose one of {", ".join(joints)}')
    return joints[name]


def _angle(joint, angle: float) -> float:
    low, high = joint.limits
    if not (math.isfinite(angle) and low <= angle <= high):
        raise CliError(
            f'--angle {angle:g} rad is outside the joint limits [{low:g}, {high:g}] rad '
            '(radians, not degrees)'
        )
    return angle


def cmd_joint_torque(args: argparse.Namespace) -> None:
    joint = _joint(args)
    theta = _angle(joint, args.angle)
    p = [gauge_pressure('--pressures', v) for v in args.pressures]
    velocity = args.velocity
    sign = math.copysign(1.0, velocity) if velocity and math.isfinite(velocity) else 0.0
    # one shot, no memory: muscle 0 shortens while θ rises (branch -1), muscle 1 lengthens (+1)
    result = joint.forward(theta, p[0], p[1], (-sign, sign))
    print(
        f'torque {float(result.torque):.6g} N·m  stiffness {float(result.stiffness):.6g} N·m/rad'
    )
    for k, name in enumerate(joint.muscle_names):
        print(
            f'{name}: length {float(joint.lengths(theta)[k]):.6g} m  force '
            f'{float(result.forces[k]):.6g} N  '
            f'dF/dL {float(result.slopes[k]):.6g} N/m  flags {describe(int(result.flags[k]))}'
        )


def cmd_joint_pressures(args: argparse.Namespace) -> None:
    joint = _joint(args)
    theta = _angle(joint, args.angle)
    torque = finite('--torque', args.torque, -1e6, 1e6, 'N·m', 'torque in newton metres')
    if args.stiffness is not None:
        result = joint.pressures_one(
            theta,
            torque,
            stiffness=finite(
                '--stiffness', args.stiffness, 0.0, 1e7, 'N·m/rad', 'stiffness in N·m/rad'
            ),
        )
    else:
        block = read_parameters(args.config)[joint.name]  # the file's defaults, as joint_node's
        level = (
            block.get('cocontraction', 0.0) if args.cocontraction is None else args.cocontraction
        )
        level = finite(
            '--cocontraction',
            gauge_pressure('--cocontraction', level),
            0.0,
            1e7,
            'Pa',
            'gauge pressure in Pa',
        )
        result = joint.pressures_one(
            theta, torque, level, args.mode or block.get('cocontraction_mode', 'min')
        )
    print(
        '  '.join(f'{name} {p:.6g} Pa' for name, p in zip(joint.muscle_names, result.pressures))
        + f'  (gauge)  flags {describe(result.flags)}'
    )
    print(
        f'torque {result.torque:.6g} N·m  stiffness {result.stiffness:.6g} N·m/rad  '
        f'reachable torque [{result.torque_range[0]:.6g}, {result.torque_range[1]:.6g}] N·m'
    )


def cmd_joint_envelope(args: argparse.Namespace) -> None:
    from ..core.physics.joint import envelope

    joint = _joint(args)
    if not 2 <= args.steps <= 10000:
        raise CliError(f'--steps {args.steps} is outside 2..10000')
    angles = np.linspace(*joint.limits, args.steps)
    env = envelope(joint, angles)
    print(
        f'{joint.name}: {joint.muscle_names[0]} shortens for positive angle; stiffness at both '
        f'pressures 0 '
        'and both at max_pressure'
    )
    print(
        f'{"angle_rad":>10}{"torque_min_Nm":>15}{"torque_max_Nm":>15}{"K_low_Nm/rad":>14}'
        f'{"K_high_Nm/rad":>15}'
    )
    for i, theta in enumerate(angles):
        print(
            f'{theta:>10.4f}{env["torque_min"][i]:>15.4f}{env["torque_max"][i]:>15.4f}'
            f'{env["stiffness_low"][i]:>14.4f}{env["stiffness_high"][i]:>15.4f}'
        )


def add_joint_commands(sub) -> None:
    """``pma-model joint torque|pressures|envelope``."""
    joint = sub.add_parser(
        'joint', help='antagonistic joint: torque, pressures for a torque, envelope'
    )
    jsub = joint.add_subparsers(dest='joint_command', required=True)
    commands = {
        'torque': ('torque and stiffness at an angle and two pressures', cmd_joint_torque),
        'pressures': ('the two pressures for a wanted torque', cmd_joint_pressures),
        'envelope': ('reachable torque and stiffness over the joint range', cmd_joint_envelope),
    }
    for name, (text, func) in commands.items():
        p = jsub.add_parser(name, help=text)
        p.add_argument(
            '--config', required=True, help='joint parameter file, e.g. config/example_joint.yaml'
        )
        p.add_argument('--joint', default=None, help="joint name (default: the file's only joint)")
        p.set_defaults(func=func)
        if name == 'envelope':
            p.add_argument(
                '--steps', type=int, default=11, help='number of angles over the limits'
            )
            continue
        p.add_argument(
            '--angle',
            required=True,
            type=float,
            help='joint angle [rad], positive counter-clockwise',
        )
        if name == 'torque':
            p.add_argument(
                '--pressures',
                required=True,
                nargs=2,
                type=float,
                metavar=('PA', 'PB'),
                help='gauge pressures [Pa]: the muscle shortening for positive angle first',
            )
            p.add_argument(
                '--velocity',
                type=float,
                default=None,
                help='joint velocity [rad/s]: its sign picks the hysteresis branches (absent: '
                'unknown, the mean of both)',
            )
        else:
            p.add_argument('--torque', required=True, type=float, help='wanted torque [N·m]')
            level = p.add_mutually_exclusive_group()
            level.add_argument('--stiffness', type=float, help='wanted stiffness [N·m/rad]')
            level.add_argument(
                '--cocontraction',
                type=float,
                default=None,
                help="co-contraction level [Pa gauge] (default: the file's cocontraction, else 0)",
            )
            p.add_argument(
                '--mode',
                choices=('min', 'sum'),
                default=None,
                help='co-contraction level is the lower pressure (min) or the pressure sum '
                "(default: the file's cocontraction_mode, else min)",
            )
