"""model_node's measured-force input and drift monitor (``residual.*``), in-process on a private
rclpy Context: messages handed to its callbacks, its /diagnostics read from its publisher.  The
expected figures are hand-calculated from the shipped files' held-out bands.  One test runs the
simulator and model_node as processes over DDS.
"""

import math

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import pytest
from sensor_msgs.msg import JointState
from test_nodes_model_node import EXAMPLE, expected_forces, frozen_clock, INPUTS, shifted

from conftest import CONFIGS
from node_messages import (
    AMBIENT,
    model_statuses,
    pressure,
    raw,
    record,
    RELIABLE_QOS,
    state,
    status_values,
)
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.nodes.model_node import ModelNode
from pma_model_ros.tools import node_process

MARTENS = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'martens')
#: config/dmsp_10_250.yaml's martens held_out: max_force 542.5 N; between 0.198 and 0.25 m the
#: worst of 4.66, 1.79, 0.41 %
MAX_FORCE, INTERIOR = 542.5, 4.65750678692


def measured(stamp, force: float) -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.stamp = stamp
    msg.wrench.force.x = force
    return msg


def node_with(private_node, params, **overrides):
    return private_node(ModelNode, '--params-file', params, overrides=overrides)


def feed(node, stamp, offset: float, n: int = 20, gauge: float = 300e3, length: float = 0.23):
    """``n`` pressure, length and measured force of one stamp each, 1 ms apart from ``stamp``;
    the measured force the served one plus ``offset`` [N].
    """
    served = float(MARTENS.force(gauge, length).force)
    for i in range(n):
        t = shifted(stamp, i * 1e-3)
        node._on_state(0, raw(state(t, length, 0.0)))
        node._on_pressure(0, raw(pressure(t, AMBIENT + gauge)))
        node._on_measured_force(0, raw(measured(t, served + offset)))
    return shifted(stamp, (n - 1) * 1e-3)


def status(node) -> object:
    sent = record(node._diag_pub)
    node.publish_status(node.now())
    return sent[-1].status[0]


def test_disabled_nothing_exists(private_node):
    node = node_with(private_node, CONFIGS['DMSP-10-250'])
    assert node.residual is None and node.inputs.residual is None
    assert '_answer' not in node.__dict__  # the plain callback
    assert not [s for s in node.subscriptions if 'measured' in s.topic_name]
    assert not [v for v in status(node).values if v.key.startswith('residual')]


def test_a_residual_above_the_band_warns_with_the_refit_command(private_node):
    node = node_with(
        private_node,
        CONFIGS['DMSP-10-250'],
        **{'residual.enabled': True, 'reidentify.enabled': True},
    )
    assert [s.topic_name for s in node.subscriptions if 'measured' in s.topic_name] == [
        '/measured_force'
    ]
    hook = node.reidentification
    hook.poll()  # enabled, active, the residual OK: watching
    assert hook.state[0] == 'watching'
    stamp = shifted(frozen_clock(node), -0.09)  # 0.09 s before now
    feed(node, stamp, 0.06 * MAX_FORCE)  # 6 % against 4.66 %: ratio 1.29
    s = status(node)
    values = {v.key: v.value for v in s.values}
    assert s.level == b'\x01', s.message
    assert s.message.startswith(
        'model drift: residual 6 % over the last 0.09 s against a band '
        'of 4.66 %: refit: pma-model fit --bag <recording>'
    )
    assert '--model martens' in s.message
    assert values['residual [% of max force]'].startswith(
        'bias 6 %, RMS 6 %, worst 6 % over 20 samples'
    )
    assert values['residual level'] == 'WARN'
    assert values['residual samples'] == '20 paired, 0 rejected, 0 unpaired, 0 unjudged'
    assert len(hook.collectors[0]) == 0  # kept only once the residual says the model drifts
    hook.poll()  # WARN: collecting
    assert hook.values(0)['reidentify state'] == 'collecting'
    feed(node, shifted(stamp, 0.02), 0.06 * MAX_FORCE)
    assert len(hook.collectors[0]) == 20  # every sample taken, as it came


def test_within_the_band_is_ok_and_bad_measured_forces_are_refused(private_node):
    node = node_with(private_node, CONFIGS['DMSP-10-250'], **{'residual.enabled': True})
    stamp = shifted(frozen_clock(node), -0.09)  # 0.09 s before now
    last = feed(node, stamp, 0.03 * MAX_FORCE)  # 3 % against 4.66 %
    node._on_measured_force(0, raw(measured(last, math.nan)))
    node._on_measured_force(0, raw(measured(last, -0.2 * MAX_FORCE)))  # below -10 %
    node._on_measured_force(0, raw(measured(last, 2.5 * MAX_FORCE)))  # above 200 %
    node._on_measured_force(0, b'\x00\x01\x00\x00\x07')  # malformed
    node._on_measured_force(0, raw(measured(shifted(last, -0.2), 100.0)))  # stale, 0.1 s
    node._on_measured_force(0, raw(measured(shifted(last, 0.005), 100.0)))  # no estimate
    s = status(node)
    values = {v.key: v.value for v in s.values}
    assert s.level == b'\x00', s.message
    assert values['residual [% of max force]'].startswith('bias 3 %, RMS 3 %, worst 3 %')
    assert f'band {INTERIOR:.3g} %' in values['residual [% of max force]']
    assert values['residual samples'] == '20 paired, 5 rejected, 1 unpaired, 0 unjudged'
    assert values['residual last refused'].startswith('stale measured force')


@pytest.mark.parametrize(
    'bad, words',
    [
        ({'residual.error_ratio': 0.5}, r'residual.error_ratio \(0.5\) must be >= residual.warn'),
        ({'residual.window': 0.0}, r"'residual.window' must be in \[0.1, 3600\] s"),
    ],
)
def test_bad_thresholds_are_refused(private_node, bad, words):
    with pytest.raises(Exception, match=words):
        node_with(private_node, CONFIGS['DMSP-10-250'], **{'residual.enabled': True} | bad)


def test_combined_measured_forces_by_name(private_node):
    node = node_with(private_node, EXAMPLE, **{'residual.enabled': True})
    stamp = shifted(frozen_clock(node), -0.05)
    expected = expected_forces(INPUTS)
    names = list(INPUTS)
    bands = {n: s.band for n, s in zip(node._names, node.settings)}
    for i in range(12):
        t = shifted(stamp, i * 1e-3)
        for topic, values in (
            ('states', [INPUTS[n][2] for n in names]),
            ('pressures', [AMBIENT + INPUTS[n][1] for n in names]),
        ):
            msg = JointState(name=names, position=values)
            msg.header.stamp = t
            getattr(node, f'_on_{topic}')(raw(msg))
        forces = JointState(
            name=names[::-1],  # any order: by name
            effort=[
                expected[n] + (0.02 * bands[n].max_force if bands[n] else 0.0) for n in names[::-1]
            ],
        )
        forces.header.stamp = t
        node._on_measured_forces(raw(forces))
    now = node.now()
    assert [n for n, b in bands.items() if b is None] == ['finger']  # its file has no held_out
    for k, name in enumerate(node._names):
        if bands[name] is None:
            assert node.residual.figures(k, now) is None
            assert 'unknown' in node.residual.values(k, None)['residual']
            continue
        f = node.residual.figures(k, now)
        assert f.samples == 12 and f.bias == pytest.approx(2, abs=1e-6), name
        assert f.band == pytest.approx(bands[name].at(INPUTS[name][2])[0]), name


@pytest.mark.ros
def test_a_drifting_simulator_makes_model_node_report_model_drift(ros, processes, namespace):
    """Over DDS: the simulator's muscle gives 60 % of its map's force (``drift.gain``); model_node
    (``residual.enabled``, its ``measured_force`` remapped to the simulator's ``force``) reports
    model drift on /diagnostics.
    """
    cmd = node_process.command(
        'model_node',
        namespace,
        CONFIGS['DMSP-10-250'],
        {'residual.enabled': True, 'residual.window': 2.0},
    )
    node = processes.start([*cmd, '-r', 'measured_force:=force'])
    sim = processes.node(
        'simulator_node',
        namespace,
        trajectory='constant',
        length=0.245,
        initial_pressure=500e3,  # about 290 N: the drift takes about 21 % of 542.5 N away
        drift__gain=0.6,
    )
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)

    def drift():
        return next(
            (s for s in model_statuses(diagnostics, namespace) if 'model drift' in s.message),
            None,
        )

    ros.spin_until(
        lambda: drift() is not None,
        40,
        'a model drift status',
        diagnose=lambda: (
            f'{(model_statuses(diagnostics, namespace) or [None])[-1]}\n'
            + processes.output(node)
            + processes.output(sim)
        ),
    )
    status = drift()
    values = status_values(status)
    assert status.level in (b'\x01', b'\x02'), status
    assert status.message.startswith('model drift: residual ') and '--model martens' in (
        status.message
    )
    assert values['residual level'] in ('WARN', 'ERROR')
    assert float(values['residual [% of max force]'].split()[1]) < -10  # bias: less than served
