"""model_node's live re-identification (``reidentify.*`` parameters) and its ``save_parameters``
service.

Measured samples come in through :meth:`LiveReidentification.add_sample` (muscle index, gauge
pressure [Pa], length [m], measured force [N]), called by the measured-force input
(``residual.enabled``) for each sample it pairs with the pressure and length of an estimate and
takes into the residual's window.  They are kept while the residual says the model no longer fits:
a muscle ``watching`` starts **collecting** when its residual level is WARN or ERROR, and collects
until its collector is full (``SampleCollector.capacity``); then its samples are dropped and it
watches again.  Nothing is kept while the node is inactive, ``reidentify.enabled`` is false or
``reidentify.freeze`` is true.

Once a muscle's samples cover the pressures and lengths it is run over well enough
(:class:`~pma_model_ros.core.runtime.reidentify.CoverageRule`), they are identified again by
:func:`~pma_model_ros.core.runtime.reidentify.reidentify` in a worker process (one, one fit at a
time, in the SCHED_IDLE class, :func:`idle_priority`: the callbacks never wait for it, the GIL is
not shared and the fit takes only CPU time the node leaves), and again each time the samples
have grown :data:`GROWTH` times since the last fit (all of them, the check samples never fitted:
the split is by arrival), and once more when the collector is full.  The result is applied by a
1 Hz timer in the executor's thread, like a parameter change (one engine configure), only if it
beat the served parameters on the check samples.  ``reidentify.freeze`` true (or
``reidentify.enabled`` false) serves the file's parameters again.

``save_parameters`` (std_srvs/Trigger) writes each muscle's served parameters as ``pma-model fit``
writes a file (:meth:`~pma_model_ros.core.runtime.reidentify.Served.save`, whole or not at all)
to ``reidentify.save_file`` (several muscles: ``<stem>.<muscle>.yaml`` beside it); empty: the ROS
log directory's ``<joint_name>_parameters.yaml``.
"""

from __future__ import annotations

from concurrent.futures import BrokenExecutor, Future, ProcessPoolExecutor
from dataclasses import replace
import multiprocessing
import os
import time

from rclpy.logging import get_logging_directory
from std_srvs.srv import Trigger

from .parameters import nest
from ..core.files.param_file import muscle_parameters, NODE_DEFAULTS, node_settings
from ..core.runtime.health import Level
from ..core.runtime.reidentify import (
    CoverageRule,
    reidentify,
    SampleCollector,
    Served,
)

#: the keys of a muscle's parameters a saved file holds: those ``fit`` writes
FILE_KEYS = (
    'muscle',
    'model',
    'length_range',
    'pressure_range',
    'models',
    'hysteresis',
    *NODE_DEFAULTS,
    'joint_name',
    'frame_id',
)


#: a muscle is identified again once its samples have grown this many times since its last fit
GROWTH = 2


def idle_priority() -> None:
    """Put every thread of this process in the SCHED_IDLE class: it runs only on a core nothing
    else wants, and any other thread that wakes takes the core at once (the scheduling class is
    per thread: the BLAS pools numpy and scipy start at import are moved too; threads started
    later inherit it).  Where that is refused, the niceness is raised to 19 instead.
    """
    try:
        threads = [int(tid) for tid in os.listdir('/proc/self/task')]
    except OSError:  # no procfs: this thread only
        threads = [0]
    for tid in threads:
        try:
            os.sched_setscheduler(tid, os.SCHED_IDLE, os.sched_param(0))
        except (OSError, AttributeError):
            os.setpriority(os.PRIO_PROCESS, tid, 19)


def save_paths(save_file: str, joints: list[str], names: list[str]) -> list[str]:
    """Where ``save_parameters`` writes each muscle's file (module docstring)."""
    if not save_file:
        return [os.path.join(get_logging_directory(), f'{j}_parameters.yaml') for j in joints]
    if len(joints) == 1:
        return [save_file]
    stem, ext = os.path.splitext(save_file)
    return [f'{stem}.{n}{ext or ".yaml"}' for n in names]


class LiveReidentification:
    """The collectors, served parameters and worker of a model_node's muscles."""

    def __init__(self, node, flat: dict, names: list[str], sources: list[str]) -> None:
        self.node = node
        nested = nest(flat)
        self.names = names
        rule = CoverageRule(
            per_cell=int(flat['reidentify.per_cell']),
            cell_share=float(flat['reidentify.cell_share']),
            lengths=int(flat['reidentify.lengths']),
        )
        self.check_every = int(flat['reidentify.check_every'])
        if rule.per_cell < 1 or not 1 <= rule.lengths <= rule.length_bins or self.check_every < 2:
            raise ValueError(
                'reidentify.per_cell must be >= 1, reidentify.lengths in [1, '
                f'{rule.length_bins}], reidentify.check_every >= 2: got {rule.per_cell}, '
                f'{rule.lengths}, {self.check_every}'
            )
        blocks = [
            {key: value for key, value in block.items() if key in FILE_KEYS}
            for block in ([muscle_parameters(nested, n) for n in names] if names else [nested])
        ]
        self.served = [Served(b, s) for b, s in zip(blocks, sources)]
        self.collectors = [SampleCollector.of(s.file.model, rule) for s in self.served]
        self.state = ['watching' if flat['reidentify.enabled'] else 'off'] * len(blocks)
        #: samples of each muscle's last fit since it started collecting (0: none)
        self.fitted = [0] * len(blocks)
        self.last = [''] * len(blocks)
        #: the model each muscle's engine config was given by :meth:`_apply`
        self._applied: list = [None] * len(blocks)
        self.sources = sources
        self._pool: ProcessPoolExecutor | None = None
        self._future: Future | None = None
        self._fitting = -1
        #: whether samples are kept (read by add_sample: one attribute test)
        self.collecting = False
        self._timer = node.create_timer(1.0, self.poll)
        self._service = node.create_service(Trigger, 'save_parameters', self.save)

    def add_sample(self, k: int, gauge: float, length: float, force: float) -> None:
        """Keep one measured sample of muscle ``k`` (nothing unless collecting)."""
        if self.collecting and self.state[k] == 'collecting':
            self.collectors[k].add(gauge, length, force)

    def _flag(self, name: str) -> bool:
        return bool(self.node.get_parameter(f'reidentify.{name}').value)

    def poll(self) -> None:
        """Apply a finished fit, start the next, follow ``enabled`` and ``freeze`` (1 Hz)."""
        enabled, frozen = self._flag('enabled'), self._flag('freeze')
        self.collecting = self.node.active and enabled and not frozen
        if not enabled or frozen:
            self._future, self._fitting = None, -1  # a fit under way is not applied
            for k, served in enumerate(self.served):
                if served.current is not served.file:
                    self._apply(k, served.revert())
                self._watch(k)  # the samples dropped
                self.state[k] = 'frozen' if enabled else 'off'
            return
        if not self.node.active:
            return
        for k, served in enumerate(self.served):
            if served.current is not served.file and (
                self.node.settings[k].config.model is not self._applied[k]
            ):  # a parameter change rebuilt the muscle from the ROS parameters: the file's model
                served.revert()
                self.last[k] = 'a parameter change served the parameters again'
        if self._future is not None and self._future.done():
            self._finish()
        for k, collector in enumerate(self.collectors):
            if self.state[k] in ('frozen', 'off'):
                self.state[k] = 'watching'
            if self.state[k] == 'watching' and self._drifting(k):
                self.state[k] = 'collecting'
            if self.state[k] != 'collecting':
                continue
            n = len(collector)
            due = n > self.fitted[k] and n >= min(GROWTH * self.fitted[k], collector.capacity)
            enough = due and collector.coverage().enough
            if enough and self._future is None:
                self._start(k)
            elif n >= collector.capacity and not enough and self._fitting != k:
                self._watch(k)  # full, nothing more to fit

    def _drifting(self, k: int) -> bool:
        """Whether muscle ``k``'s residual level is WARN or ERROR."""
        residual = self.node.residual
        return residual is not None and residual.levels[k] >= Level.WARN

    def _watch(self, k: int) -> None:
        """Drop muscle ``k``'s samples; it collects again when its residual drifts."""
        self.collectors[k].clear()
        self.fitted[k], self.state[k] = 0, 'watching'

    def _start(self, k: int) -> None:
        if self._pool is None:  # a fresh interpreter: no copy of the node's threads or DDS state
            self._pool = ProcessPoolExecutor(
                1,
                mp_context=multiprocessing.get_context('spawn'),
                initializer=idle_priority,  # the estimates first: the fit takes what is left
            )
        samples = self.collectors[k].samples()
        self._fitting = k  # it collects on meanwhile
        self._future = self._pool.submit(
            reidentify, self.served[k].current.parameters, samples, self.check_every
        )
        self._future.samples = len(samples)

    def _finish(self) -> None:
        k, future = self._fitting, self._future
        self._future, self._fitting = None, -1
        self.fitted[k] = future.samples
        try:
            outcome = future.result()
        except Exception as err:  # a fit that failed (or its worker ended): collect on
            if isinstance(err, BrokenExecutor):
                self._pool = None  # the next fit starts a new worker
            self.last[k] = f'refused: {type(err).__name__}: {err}'
            return
        self.last[k] = outcome.describe()
        if outcome.accepted:
            served = self.served[k]
            source = self.sources[k]
            self._apply(k, served.swap(outcome, future.samples, source, time.time()))
            self.node.get_logger().info(f'{self.node.settings[k].joint_name}: {self.last[k]}')

    def _apply(self, k: int, snapshot) -> None:
        """Serve ``snapshot`` for muscle ``k``: one engine configure, as a parameter change."""
        node = self.node
        if node.engine is None:
            return
        old = node.settings[k]
        new = replace(
            node_settings(snapshot.parameters),
            joint_name=old.joint_name,
            frame_id=old.frame_id,
            hardware_id=old.hardware_id,
        )
        self._applied[k] = new.config.model
        settings = [*node.settings[:k], new, *node.settings[k + 1 :]]
        node.engine.configure([s.config for s in settings])
        node.settings = settings
        node.use(settings)

    def values(self, k: int) -> dict[str, str]:
        """The muscle's /diagnostics keys of re-identification."""
        served = self.served[k]
        if self.state[k] == 'off':
            return {}
        return {
            'reidentify state': 'fitting' if self._fitting == k else self.state[k],
            'reidentify coverage': self.collectors[k].coverage().describe(),
            'reidentify last': self.last[k] or 'none',
            'reidentify served': 'file' if served.current is served.file else 're-identified',
        }

    def save(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """``save_parameters``: write every muscle's served parameters (module docstring)."""
        paths = save_paths(
            str(self.node.get_parameter('reidentify.save_file').value),
            [s.joint_name for s in self.node.settings],
            self.names,
        )
        try:
            for served, path in zip(self.served, paths):
                served.save(path)
        except (OSError, ValueError) as err:
            response.success, response.message = False, f'not saved: {err}'
            return response
        response.success, response.message = True, ', '.join(paths)
        return response

    def close(self) -> None:
        """Destroy the service (the timer is the managed node's, destroyed with its entities), stop
        the worker.
        """
        self.collecting = False
        self.node.destroy_service(self._service)
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
