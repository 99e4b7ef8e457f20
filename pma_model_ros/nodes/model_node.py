"""model_node: force estimates and pressure commands of one or many identified pneumatic muscles.

One muscle (parameters at the top level): subscribes ``pressure`` (sensor_msgs/FluidPressure,
absolute Pa), ``muscle_state`` (sensor_msgs/JointState: position = length [m], velocity =
length rate [m/s]) and ``force_command`` (geometry_msgs/WrenchStamped, force.x = wanted
tension [N]); publishes ``force_estimate`` (WrenchStamped, force.x = tension [N]),
``pressure_command`` (FluidPressure, absolute Pa) and ``/diagnostics``.

Many muscles (``muscles: [a, b, ...]``, each one's parameters under ``<name>.``): the same
topics under ``<name>/`` (``input_mode: per_muscle``), or (``input_mode: combined``) one
``muscle_states`` JointState with every length, one ``muscle_pressures`` JointState with every
absolute pressure [Pa] in ``position``, answered by one ``force_estimates`` JointState
(effort = tension [N]), all muscles evaluated in one vectorised call per model
(:class:`~pma_model_ros.core.muscle_bank.MuscleBank`); commands come in one ``force_commands``
JointState (effort = wanted tension [N]) and go out in one ``pressure_commands`` JointState
(position = absolute pressure [Pa]).  The decisions live in :mod:`pma_model_ros.core.estimator`,
one Estimator per muscle.
"""
from __future__ import annotations

from functools import partial, reduce
from itertools import islice
import operator
import sys
from typing import Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
import numpy as np
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rcl_interfaces.msg import SetParametersResult
from sensor_msgs.msg import FluidPressure, JointState

from ..core.estimator import WARN_FLAGS, Estimate, Estimator, Pair, joint_problem
from ..core.muscle_bank import MuscleBank
from ..core.param_file import NodeSettings
from . import model_params
from .ros_time import now_seconds, seconds
from .startup import StartupError, run

DIAGNOSTIC_PERIOD = 1.0  # [s]; also how long a bad input or a warning holds the level up
#: Flags after which a muscle's diagnostic level may have risen (checked at once, not at the next report).
WARN_MASK = int(reduce(operator.or_, WARN_FLAGS))

#: Inputs: sensor-data QoS (best effort, volatile) with a queue of 100 instead of 5 (0.1 s at 1 kHz): a
#: briefly stalled node catches up, and inputs older than max_input_age are counted stale (ERROR),
#: instead of being dropped unseen.
INPUT_QOS = QoSProfile(depth=100, reliability=qos_profile_sensor_data.reliability,
                       durability=qos_profile_sensor_data.durability, history=qos_profile_sensor_data.history)

class JointIndex:
    """Where each joint sits in the arrays of a JointState; the last valid name layout is cached."""

    def __init__(self, joints: Sequence[str]) -> None:
        self.joints = list(joints)
        self._names: list[str] | None = None
        self._index: list[int | str] = []

    def of(self, names: list[str], values: Sequence[float], velocities: Sequence[float]) -> list[int | str]:
        """Per joint, its index in ``values``, or why it has none (:func:`joint_problem`)."""
        if names == self._names:   # same layout as before: every joint is there; only array sizes can differ
            problem = joint_problem(names, values, velocities, self.joints[0])
            return [problem] * len(self.joints) if problem else self._index
        index = [joint_problem(names, values, velocities, joint) or names.index(joint) for joint in self.joints]
        if all(isinstance(i, int) for i in index):
            self._names, self._index = list(names), index
        return index


class ModelNode(Node):
    """Thin ROS shell around one :class:`Estimator` per muscle and one :class:`MuscleBank`."""

    def __init__(self) -> None:
        super().__init__("model_node")
        try:
            self._names, self._mode = model_params.declare(self)
            self._settings = model_params.all_settings(model_params.values(self), self._names)
        except (ParameterException, ValueError) as err:
            raise StartupError(str(err)) from None
        self._estimators = [Estimator(s.config, hold=DIAGNOSTIC_PERIOD) for s in self._settings]
        self._use(self._settings)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)

        sensor = INPUT_QOS
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        if self._mode == "combined":   # few entities: an executor's cost per wake grows with their number
            self._states_pub = self.create_publisher(JointState, "force_estimates", 10)
            self._commands_pub = self.create_publisher(JointState, "pressure_commands", 10)
            self.create_subscription(JointState, "muscle_pressures", self._on_pressures, sensor)
            self.create_subscription(JointState, "muscle_states", self._on_states, sensor)
            self.create_subscription(JointState, "force_commands", self._on_commands, 10)
        else:
            prefixes = [f"{name}/" for name in self._names] or [""]
            self._estimate_pubs = [self.create_publisher(WrenchStamped, f"{p}force_estimate", 10) for p in prefixes]
            self._estimate_msgs = [WrenchStamped() for _ in prefixes]
            self._command_pubs = [self.create_publisher(FluidPressure, f"{p}pressure_command", 10) for p in prefixes]
            for k, prefix in enumerate(prefixes):
                self.create_subscription(FluidPressure, f"{prefix}pressure", partial(self._on_pressure, k), sensor)
                self.create_subscription(JointState, f"{prefix}muscle_state", partial(self._on_state, k), sensor)
                self.create_subscription(WrenchStamped, f"{prefix}force_command", partial(self._on_command, k), 10)
        self.create_timer(DIAGNOSTIC_PERIOD, lambda: self._publish_status(now_seconds(self)))
        muscles = [f"{s.config.model.spec.name} with model {s.config.model.model.name}, joint '{s.joint_name}'"
                   for s in self._settings]
        self.get_logger().info(muscles[0] if not self._names else f"{len(muscles)} muscles, {self._mode}: "
                               + "; ".join(muscles))

    def _use(self, settings: list[NodeSettings]) -> None:
        """Swap in new settings: each estimator's config; in combined mode the bank, joint layout and output."""
        self._settings = settings
        for estimator, s in zip(self._estimators, settings):
            estimator.config = s.config   # one immutable object per muscle: atomic swap
        if self._mode != "combined":
            return
        self._bank = MuscleBank([s.config.model for s in settings])
        joints = [s.joint_name for s in settings]
        self._pressure_index, self._state_index = JointIndex(joints), JointIndex(joints)
        n = len(settings)
        self._idle = [(0.0, s.config.model.domain.length_max, None) for s in settings]
        self._estimates_msg = JointState(name=joints, effort=[0.0] * n)
        self._effort_view = np.frombuffer(self._estimates_msg.effort, dtype=float)   # writes into the message

    def _validate(self, changes: list[Parameter]) -> SetParametersResult:
        """Accept a change only if the whole would-be parameter set builds every muscle."""
        flat = model_params.values(self)
        flat.update({p.name: model_params.plain(p.value) for p in changes})
        try:
            model_params.all_settings(flat, self._names)
        except ValueError as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply(self, _changes: list[Parameter]) -> None:
        self._use(model_params.all_settings(model_params.values(self), self._names))

    # one muscle per message: per_muscle topics (and the one-muscle node)

    def _on_pressure(self, k: int, msg: FluidPressure) -> None:
        now = now_seconds(self)
        estimator = self._estimators[k]
        pair = estimator.pressure(msg.fluid_pressure, seconds(msg.header.stamp), now, msg.header.stamp)
        self._publish_estimate(k, estimator.estimate(pair, now))
        self._check_level(k, now)

    def _on_state(self, k: int, msg: JointState) -> None:
        now = now_seconds(self)
        estimator = self._estimators[k]
        pair = estimator.joint_state(msg.name, msg.position, msg.velocity, self._settings[k].joint_name,
                                     seconds(msg.header.stamp), now, msg.header.stamp)
        self._publish_estimate(k, estimator.estimate(pair, now))
        self._check_level(k, now)

    def _publish_estimate(self, k: int, estimate: Estimate | None) -> None:
        if estimate is None:
            return
        msg = self._estimate_msgs[k]
        msg.header.stamp = estimate.tag
        msg.header.frame_id = self._settings[k].frame_id
        msg.wrench.force.x = estimate.force
        self._estimate_pubs[k].publish(msg)

    def _on_command(self, k: int, msg: WrenchStamped) -> None:
        now = now_seconds(self)
        command = self._estimators[k].command(msg.wrench.force.x, now)
        if command is not None:
            out = FluidPressure(fluid_pressure=command.pressure)
            out.header.stamp = self.get_clock().now().to_msg()
            out.header.frame_id = self._settings[k].frame_id
            self._command_pubs[k].publish(out)
        self._check_level(k, now)

    # all muscles per message: the combined mode

    def _on_pressures(self, msg: JointState) -> None:
        now, stamp, tag, values = now_seconds(self), seconds(msg.header.stamp), msg.header.stamp, msg.position
        self._answer([estimator.pressure(values[i], stamp, now, tag) if isinstance(i, int)
                      else estimator.reject("pressure", i, now)
                      for estimator, i in zip(self._estimators, self._pressure_index.of(msg.name, values, ()))], now)

    def _on_states(self, msg: JointState) -> None:
        now, stamp, tag = now_seconds(self), seconds(msg.header.stamp), msg.header.stamp
        values, rates = msg.position, msg.velocity
        has_rates = len(rates) > 0
        self._answer([estimator.length(values[i], rates[i] if has_rates else None, stamp, now, tag)
                      if isinstance(i, int) else estimator.reject("muscle_state", i, now)
                      for estimator, i in zip(self._estimators, self._state_index.of(msg.name, values, rates))], now)

    def _answer(self, pairs: list[Pair | None], now: float) -> None:
        """Evaluate every muscle's pair in one bank call, accept each, publish one force_estimates."""
        rows = [pair or idle for pair, idle in zip(pairs, self._idle)]   # idle: valid inputs, result unused
        gauge, length, rate = (np.array(column, dtype=float) for column in islice(zip(*rows), 3))  # None: NaN
        result = self._bank.force(gauge, length, rate)
        accepted = [None if pair is None else estimator.accept(pair, force, flags, now) for estimator, pair, force, flags
                    in zip(self._estimators, pairs, result.force.tolist(), result.flags.tolist())]
        if any(e is not None for e in accepted):
            self._states_pub.publish(self._estimates(accepted, result.force))
        if any(self._estimators[k].status_due(now) for k, (estimate, flags)
               in enumerate(zip(accepted, result.flags.tolist())) if estimate is None or flags & WARN_MASK):
            self._publish_status(now)

    def _on_commands(self, msg: JointState) -> None:
        """Pressure commands of the muscles named in ``msg`` (the others are not commanded)."""
        now, names, forces = now_seconds(self), msg.name, msg.effort
        problem = "" if len(forces) == len(names) else f"mismatched arrays: {len(names)} names, {len(forces)} efforts"
        out = JointState()
        changed = False
        for k, (estimator, s) in enumerate(zip(self._estimators, self._settings)):
            if s.joint_name not in names:
                continue
            if problem:
                estimator.reject("force_command", problem, now)
            elif (command := estimator.command(forces[names.index(s.joint_name)], now)) is not None:
                out.name.append(s.joint_name)
                out.position.append(command.pressure)
            changed |= estimator.status_due(now)
        if out.name:
            out.header.stamp = self.get_clock().now().to_msg()
            self._commands_pub.publish(out)
        if changed:
            self._publish_status(now)

    def _estimates(self, accepted: list[Estimate | None], forces: np.ndarray) -> JointState:
        """The force_estimates message of each muscle's estimate (None: none): the prebuilt one when all have one."""
        if None not in accepted:
            msg = self._estimates_msg
            self._effort_view[:] = forces
        else:
            msg = JointState(name=[s.joint_name for s, e in zip(self._settings, accepted) if e is not None],
                             effort=[e.force for e in accepted if e is not None])
        msg.header.stamp = max((e for e in accepted if e is not None), key=operator.attrgetter("stamp")).tag
        return msg

    # diagnostics: one status per muscle in one array

    def _check_level(self, k: int, now: float) -> None:
        if self._estimators[k].status_due(now):
            self._publish_status(now)

    def _publish_status(self, now: float) -> None:
        node = self.get_fully_qualified_name()
        statuses = []
        for k, (estimator, s) in enumerate(zip(self._estimators, self._settings)):
            status = estimator.status(now)
            statuses.append(DiagnosticStatus(
                level=bytes([status.level]), name=f"{node}: {s.joint_name}", message=status.message,
                hardware_id=s.config.model.spec.name,
                values=[KeyValue(key=key, value=value) for key, value in status.values.items()]))
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run("model_node", ModelNode, args)


if __name__ == "__main__":
    sys.exit(main())
