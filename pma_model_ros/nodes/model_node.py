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
JointState (position = absolute pressure [Pa]).  With ``forward_command_topic``, every muscle's
pressure command also goes out in one std_msgs/Float64MultiArray per command message that
commanded one, in ``forward_command_order`` (by ``joint_name``), for ros2_control's
forward_command_controller (:mod:`pma_model_ros.wire.forward_commands`: the others' last values;
nothing until every muscle had a command).  With ``residual.enabled``, a measured force per muscle
(``measured_force``, WrenchStamped force.x [N]; combined: one ``measured_forces`` JointState,
effort [N] by muscle name) is paired by stamp with the estimate of the same inputs and judged by
:class:`~pma_model_ros.core.runtime.residual.Residuals` (model drift in /diagnostics); each sample
it takes also goes to live re-identification (:mod:`.live_reidentification`).  Disabled, nothing of
it exists: no subscription, and the estimates' callbacks are the plain ones.  Every decision is the
:class:`~pma_model_ros.core.runtime.engine.Engine`'s.  Subscriptions are raw: the wire layer
(:mod:`pma_model_ros.wire.muscle_inputs`) reads the bytes into its calls and writes the answers'
bytes; every entity is created in :meth:`ModelNode.create_interfaces`, by the ``configure``
transition: the node is managed (:mod:`.managed`) and answers only while active.
"""

from __future__ import annotations

from functools import partial
import sys
from time import time_ns

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64MultiArray

from . import model_params
from .live_reidentification import LiveReidentification
from .managed import ManagedNode
from .parameters import warn_unknown
from .qos import (
    only_overrides,
    publisher,
    RELIABLE,
    SENSOR_INPUT,
    subscription,
    warn_unknown_overrides,
)
from .rclpy_private import parameter_overrides, take, with_message_info
from .startup import run
from ..core.files.node_parameters import SPECS, topic_prefixes
from ..core.files.param_file import node_engine, node_pairing, NodeSettings
from ..core.runtime.engine import Engine
from ..core.runtime.pairing import nanoseconds, QueueDelay
from ..core.runtime.residual import Residuals, Thresholds
from ..wire.cdr import fluid_pressure, Template
from ..wire.forward_commands import forward_order, ForwardCommands
from ..wire.muscle_inputs import MuscleInputs

#: rclpy's deserializers of the input types: what the wire layer's fast readers do not read.
DESERIALIZE = {
    kind.__name__: partial(lambda kind, data: deserialize_message(data, kind), kind)
    for kind in (FluidPressure, JointState, WrenchStamped)
}


class ModelNode(ManagedNode):
    """Thin ROS shell around one :class:`Engine` for all its muscles; a managed node
    (:mod:`.managed`): it answers inputs only while active.
    """

    def __init__(self, **kwargs) -> None:
        self._blocks: model_params.ModelBlocks | None = None  # the parameters' own state
        self.engine: Engine | None = None
        #: live re-identification (:mod:`.live_reidentification`), built by configure
        self.reidentification: LiveReidentification | None = None
        #: the measured forces' monitor (``residual.enabled``; built by reset), else None
        self.residual: Residuals | None = None
        self._thresholds: Thresholds | None = None
        super().__init__('model_node', **kwargs)

    def declare_all(self) -> None:
        """Declare every parameter; the first time, the model blocks and the set-parameters
        callbacks (they outlive a cleanup).
        """
        self._names, self.mode = model_params.declare(self)
        if self._blocks is None:
            self._blocks = model_params.ModelBlocks(self, self._names)
            self.add_pre_set_parameters_callback(self._blocks.hold)
            self.add_on_set_parameters_callback(self._validate)
            self.add_post_set_parameters_callback(self._apply)

    def configure(self) -> None:
        """Read and check the parameters, build the engine, warn about unknown parameters; then,
        last, create every ROS entity (nothing is matched before the node can answer).
        """
        self.declare_all()
        flat = self._blocks.would_be([])
        self.settings = model_params.all_settings(flat, self._names, self.instance)
        self._pairing = node_pairing(flat)
        self._max_answer_delay = flat.get('max_answer_delay', SPECS['max_answer_delay'].default)
        #: [ns] an input that waited longer than this is not answered (_newest)
        self._max_queue_delay = nanoseconds(
            flat.get('max_queue_delay', SPECS['max_queue_delay'].default)
        )
        self._thresholds = (
            Thresholds(
                *(
                    float(flat.get(f'residual.{name}', SPECS[f'residual.{name}'].default))
                    for name in ('window', 'warn_ratio', 'error_ratio', 'hysteresis')
                )
            )
            if flat.get('residual.enabled', False)
            else None
        )
        self._forward_order = (
            forward_order(
                list(flat.get('forward_command_order') or []),
                [s.joint_name for s in self.settings],
                "muscle's joint_name",
            )
            if flat.get('forward_command_topic')
            else None
        )
        self.reset()
        warn_unknown(self, model_params.expected_undeclared)
        muscles = [
            f'{s.config.model.spec.name} with model {s.config.model.model.name}, joint '
            f"'{s.joint_name}'"
            for s in self.settings
        ]
        self.get_logger().info(
            muscles[0]
            if not self._names
            else f'{len(muscles)} muscles, {self.mode}: ' + '; '.join(muscles)
        )
        self.create_interfaces()
        self.reidentification = LiveReidentification(
            self,
            flat,
            self._names,
            [f'the parameters model_node {self.instance} started with'] * len(self.settings),
        )

    def status_names(self) -> list[tuple[str, str]]:
        return [(s.joint_name, s.hardware_id) for s in self.settings]

    def reset(self) -> None:
        """A fresh engine of the current settings (no input known, counters at zero), and no
        forwarded command known.
        """
        self.engine = node_engine(
            self.settings, **self._pairing, max_answer_delay=self._max_answer_delay
        )
        if self._thresholds is not None:
            self.residual = Residuals(
                *self._judged(self.settings), self.engine.pairing.max_age, self._thresholds
            )
            self._answer = self._answer_recorded  # (the plain _answer when disabled)
        self.use(self.settings)
        joints = [s.joint_name for s in self.settings]
        self._forward = (
            ForwardCommands(self._forward_order, [[j] for j in joints])
            if self._forward_order
            else None
        )

    def release(self) -> None:
        if self.reidentification is not None:
            self.reidentification.close()
            self.reidentification = None
        self.engine = self.inputs = self._forward = self.residual = None
        self.__dict__.pop('_answer', None)
        self._estimate_pubs = self._command_pubs = []

    def create_interfaces(self) -> None:
        """Every subscription and publisher of the node (raw subscriptions: bytes in), each QoS
        overridable by parameters (:mod:`.qos`).
        """
        self._diag_pub = publisher(self, DiagnosticArray, '/diagnostics', RELIABLE)
        forward = self._forward_order is not None  # (then the commands' callbacks forward too)
        if forward:
            topic = self.get_parameter('forward_command_topic').value
            self._forward_pub = publisher(self, Float64MultiArray, topic, RELIABLE)
        count = 1 if self.mode == 'combined' else len(self.settings)
        #: each sensor topic's subscription and queue wait (_newest), by input and muscle
        #: (combined: one)
        self._waits = {
            s: [QueueDelay() for _ in range(count)] for s in ('pressure', 'muscle_state')
        }
        self._queues: dict[str, list] = {'pressure': [], 'muscle_state': []}
        if self.mode == 'combined':
            self._estimate_pubs = [publisher(self, JointState, 'force_estimates', RELIABLE)]
            self._command_pubs = [publisher(self, JointState, 'pressure_commands', RELIABLE)]
            for topic, callback, qos, source in (
                ('muscle_pressures', self._on_pressures, SENSOR_INPUT, 'pressure'),
                ('muscle_states', self._on_states, SENSOR_INPUT, 'muscle_state'),
                (
                    'force_commands',
                    self._forward_commands if forward else self._on_commands,
                    RELIABLE,
                    None,
                ),
            ):
                self._timed(subscription(self, JointState, topic, callback, qos, raw=True), source)
            if self._thresholds is not None:
                subscription(
                    self,
                    JointState,
                    'measured_forces',
                    self._on_measured_forces,
                    SENSOR_INPUT,
                    raw=True,
                )
        else:
            self._per_muscle_topics(forward)
        warn_unknown_overrides(self, parameter_overrides(self))

    def _per_muscle_topics(self, forward: bool) -> None:
        """The topics of each muscle, under ``<name>/`` (one muscle: at the node's namespace);
        ``forward``: its force_command's callback forwards the pressure commands too.
        """
        prefixes = topic_prefixes(self._names)
        self._estimate_pubs = [
            publisher(self, WrenchStamped, f'{p}force_estimate', RELIABLE) for p in prefixes
        ]
        self._command_pubs = [
            publisher(self, FluidPressure, f'{p}pressure_command', RELIABLE) for p in prefixes
        ]
        for k, p in enumerate(prefixes):
            for kind, topic, callback, qos, source in (
                (FluidPressure, 'pressure', self._on_pressure, SENSOR_INPUT, 'pressure'),
                (JointState, 'muscle_state', self._on_state, SENSOR_INPUT, 'muscle_state'),
                (
                    WrenchStamped,
                    'force_command',
                    self._forward_command if forward else self._on_command,
                    RELIABLE,
                    None,
                ),
            ):
                sub = subscription(self, kind, p + topic, partial(callback, k), qos, raw=True)
                self._timed(sub, source)
            if self._thresholds is not None:
                callback = partial(self._on_measured_force, k)
                subscription(
                    self, WrenchStamped, p + 'measured_force', callback, SENSOR_INPUT, raw=True
                )

    def _timed(self, sub, source: str | None) -> None:
        """A sensor input's subscription (``source``: pressure or muscle_state) gets each
        message's info, where the executor passes it (:attr:`reception_times`); a command's
        (None) does not.
        """
        if source is not None:
            self._queues[source].append(sub)
            if self.reception_times:
                with_message_info(sub)

    def use(self, settings: list[NodeSettings]) -> None:
        """Translate messages for the muscles of ``settings`` (their joint names and frames)."""
        self.inputs = MuscleInputs(
            self.engine,
            [s.joint_name for s in settings],
            [s.frame_id for s in settings],
            DESERIALIZE,
            self.residual,
        )
        if self.residual is not None:
            self.residual.use(*self._judged(settings))
        self._commands = [fluid_pressure(s.frame_id) for s in settings]

    @staticmethod
    def _judged(settings: list[NodeSettings]) -> tuple[list, list[float], list[str]]:
        """What the residual monitor judges each muscle by: its held-out band, identified gauge
        pressures' top [Pa] and model.
        """
        return (
            [s.band for s in settings],
            [s.config.model.domain.pressure_max for s in settings],
            [s.config.model.model.name for s in settings],
        )

    def _validate(self, changes: list[Parameter]) -> SetParametersResult:
        """Accept a change only if the whole would-be parameter set builds every muscle."""
        if not self._blocks.swapping and not only_overrides(changes):
            try:
                model_params.all_settings(self._blocks.would_be(changes), self._names)
            except ValueError as err:
                return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply(self, changes: list[Parameter]) -> None:
        """Swap a good change in atomically (unconfigured: the next configure reads it), and log
        it.
        """
        if self._blocks.swapping or only_overrides(changes):
            return
        flat = self._blocks.applied()
        told = ', '.join(f'{p.name} = {p.value!r}' for p in changes)
        if self.engine is None:
            self.get_logger().info(f'parameters set: {told} (read by the next configure)')
            return
        settings = model_params.all_settings(flat, self._names, self.instance)
        self.engine.configure([s.config for s in settings])
        self.settings = settings
        self.use(settings)
        self.get_logger().info(f'parameters set: {told}')

    # --- callbacks: bytes in, bytes out, only while active (the gate: the first line).  With
    # DDS's message info (``info``), an input that waited longer than max_queue_delay makes the
    # node take what waits behind it and answer the newest (_newest).
    def _on_pressure(self, k: int, data: bytes, info: dict | None = None) -> None:
        if not self.active:
            return
        if info is not None and (data := self._newest(data, info, 0, k)) is None:
            return
        now = self.now()
        self._answer(k, self.inputs.pressure(k, data, now), now, info, k)

    def _on_state(self, k: int, data: bytes, info: dict | None = None) -> None:
        if not self.active:
            return
        if info is not None and (data := self._newest(data, info, 1, k)) is None:
            return
        now = self.now()
        self._answer(k, self.inputs.muscle_state(k, data, now), now, info, k)

    def _on_pressures(self, data: bytes, info: dict | None = None) -> None:
        if not self.active or info is not None and (data := self._newest(data, info, 0)) is None:
            return
        now = self.now()
        self._answer(0, self.inputs.pressures(data, now), now, info, None)

    def _on_states(self, data: bytes, info: dict | None = None) -> None:
        if not self.active or info is not None and (data := self._newest(data, info, 1)) is None:
            return
        now = self.now()
        self._answer(0, self.inputs.states(data, now), now, info, None)

    def _newest(self, data: bytes, info: dict, side: int, k: int | None = None) -> bytes | None:
        """The input to answer of a sensor topic (``side`` 0: pressure, 1: muscle_state) of muscle
        ``k`` (None: every muscle): ``data`` itself if it waited at most ``max_queue_delay``
        (:class:`QueueDelay`); else the newest of those waiting behind it in the queue, each
        older one counted as skipped unread, and None (all skipped) if the newest waited too long
        as well.  The answered input's wait [ns] and when it was taken [ns, system clock] are kept
        for :meth:`_answer`.
        """
        source, i = ('pressure', 'muscle_state')[side], k or 0
        queue = self._waits[source][i]
        taken = time_ns()
        waited = queue.waited(info['source_timestamp'], info['received_timestamp'], taken)
        if waited > self._max_queue_delay:
            subscription = self._queues[source][i]
            while (behind := take(subscription)) is not None:
                self.engine.behind(source, k)
                data, info = behind
                taken = time_ns()
                waited = queue.waited(info['source_timestamp'], info['received_timestamp'], taken)
            if waited > self._max_queue_delay:
                self.engine.behind(source, k)
                now = self.now()
                if self.engine.status_due(now):
                    self.publish_status(now)
                return None
        self._waited, self._taken = waited, taken
        return data

    def _answer(
        self, k: int, estimate: bytes | None, now: int, info: dict | None, muscle: int | None
    ) -> None:
        """Publish ``estimate`` on publisher ``k``; with ``info``, its delay since the input
        would have arrived (of ``muscle``; None: of every muscle) to the engine.
        """
        if estimate is not None:
            self._estimate_pubs[k].publish(estimate)
            if info is not None:
                self.engine.answered(muscle, self._waited + time_ns() - self._taken, now)
        if self.engine.status_due(now):  # (inline: the hot path)
            self.publish_status(now)

    def _answer_recorded(
        self, k: int, estimate: bytes | None, now: int, info: dict | None, muscle: int | None
    ) -> None:
        """:meth:`_answer`, after keeping the estimate for the measured force of its stamp
        (``residual.enabled``).
        """
        if estimate is not None:
            self.inputs.served(muscle)
        ModelNode._answer(self, k, estimate, now, info, muscle)

    # --- with residual.enabled: the measured forces
    def _on_measured_force(self, k: int, data: bytes) -> None:
        if self.active and (sample := self.inputs.measured_force(k, data, self.now())):
            if self.reidentification.collecting:
                self.reidentification.add_sample(k, *sample)

    def _on_measured_forces(self, data: bytes) -> None:
        if self.active:
            taken = self.inputs.measured_forces(data, self.now())
            if self.reidentification.collecting:  # (one test per message while it is not)
                for sample in zip(*(a.tolist() for a in taken)):
                    self.reidentification.add_sample(*sample)

    def _on_command(self, k: int, data: bytes) -> float | None:
        """A ``force_command`` of muscle ``k``; the pressure commanded, if any."""
        if not self.active:
            return None
        now = self.now()
        pressure = self.inputs.force_command(k, data, now)
        if pressure is not None:
            command = self._commands[k]
            command.values[0] = pressure
            self._command_pubs[k].publish(command(now))
        if self.engine.status_due(now):  # (inline: the hot path)
            self.publish_status(now)
        return pressure

    def _on_commands(self, data: bytes) -> Template | None:
        """Pressure commands of the muscles named in the message (the others are not commanded);
        the message published, if any.
        """
        if not self.active:
            return None
        now = self.now()
        commands = self.inputs.force_commands(data, now)
        if commands is not None:
            self._command_pubs[0].publish(commands(now))
        if self.engine.status_due(now):  # (inline: the hot path)
            self.publish_status(now)
        return commands

    # --- with forward_command_topic: the commands' callbacks, then the array
    def _forward_command(self, k: int, data: bytes) -> None:
        if (pressure := self._on_command(k, data)) is not None:
            self._forward.command(k, (pressure,))
            self._publish_forward()

    def _forward_commands(self, data: bytes) -> None:
        if (commands := self._on_commands(data)) is not None:
            for k, pressure in zip(self.inputs.commanded, commands.values.tolist()):
                self._forward.command(k, (pressure,))
            self._publish_forward()

    def _publish_forward(self) -> None:
        if (message := self._forward.message()) is not None:
            self._forward_pub.publish(message)

    def publish_status(self, now: int) -> None:
        """One DiagnosticStatus per muscle in one DiagnosticArray: the engine's status, the
        identification results and the expected error at the muscle's newest length.
        """
        entries = [
            s.status_entry(status, self.engine.inputs(k)[1])
            for k, (s, status) in enumerate(zip(self.settings, self.engine.statuses(now)))
        ]
        if self.reidentification is not None:
            values = self.reidentification.values
            entries = [(*e[:4], e[4] | values(k)) for k, e in enumerate(entries)]
        if self.residual is not None:
            entries = [self._with_residual(k, e, now) for k, e in enumerate(entries)]
        self.publish_entries(entries, now)

    def _with_residual(self, k: int, entry: tuple, now: int) -> tuple:
        """Muscle ``k``'s status ``entry`` with its residual: the keys, and the drift's level and
        message where it is not OK (the worse level; the drift's message first if it is worse).
        """
        name, hardware_id, level, message, values = entry
        drift, text, figures = self.residual.report(k, now)
        values = values | self.residual.values(k, figures)
        if drift > level:
            return name, hardware_id, int(drift), f'{text}; {message}' if level else text, values
        if drift:
            return name, hardware_id, level, f'{message}; {text}', values
        return name, hardware_id, level, message, values


def main(args: list[str] | None = None) -> int:
    return run('model_node', ModelNode, args)


if __name__ == '__main__':
    sys.exit(main())
