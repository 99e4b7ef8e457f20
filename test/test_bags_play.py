"""Bags over DDS: a recording replayed into the running model node gives the offline estimates,
message for message; the simulator node records what it publishes.
"""

from pathlib import Path
import sys

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest

try:
    import rosbags  # noqa: F401
except ImportError:  # pip-only (a -pip rosdep key): colcon test on a ROS install without it
    pytest.skip(
        'needs rosbags, a pip-only library: pip install -r requirements-dev.txt',
        allow_module_level=True,
    )
from rosgraph_msgs.msg import Clock

from conftest import CONFIGS
from node_messages import model_statuses, RELIABLE_QOS, SENSOR_QOS, stamp_key, status_values
from pma_model_ros.bags.bag_io import qos, read, storage_of
from pma_model_ros.bags.estimate import estimate_bag
from pma_model_ros.bags.synthetic import record_simulation, START_NS
from pma_model_ros.core.files.param_file import node_settings, read_parameters
from pma_model_ros.tools import node_process

pytestmark = pytest.mark.ros

NOISE = {'noise__pressure_std': 200.0, 'noise__length_std': 2e-5, 'noise__force_std': 0.5}


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_replay_into_the_node_equals_offline_estimate(
    ros, processes, namespace, tmp_path, storage
):
    bag = record_simulation(
        tmp_path / 'rec',
        3.0,
        namespace,
        storage,
        rate=100.0,
        period=2.0,
        sweep_period=3.0,
        seed=5,
        offered=qos(reliable=True, depth=1000),
        **NOISE,
    )
    estimate_bag(
        bag,
        node_settings(read_parameters(CONFIGS['DMSP-10-250'])),
        tmp_path / 'offline',
        progress=False,
    )
    offline = [
        (stamp_key(m), m.wrench.force.x)
        for _, _, m in read(tmp_path / 'offline', [f'{namespace}/force_estimate'])
    ]
    assert len(offline) == 599

    # every replayed input answered, as offline, however long it waits in a loaded node's queue
    # (live, a node that falls behind answers only its newest inputs: test_nodes_faults.py) and
    # however far the played /clock has moved on meanwhile (live, an input older than
    # max_input_age on the node's clock is stale: test_bad_input_matrix.py); and nothing lost on
    # the way: the recording offers reliable QoS with room for all its messages, and so do the
    # node's inputs and estimates (best effort, or a reliable writer's history of 10, drop
    # messages when a loaded reader stalls)
    config = CONFIGS['DMSP-10-250']
    lossless = {
        f'qos_overrides.{namespace}/{name}.{end}.{policy}': value
        for name, end in (
            ('pressure', 'subscription'),
            ('muscle_state', 'subscription'),
            ('force_estimate', 'publisher'),
        )
        for policy, value in (('reliability', 'reliable'), ('depth', 1000))
    }
    node = processes.node(
        'model_node',
        namespace,
        config,
        use_sim_time='true',
        max_queue_delay=3600.0,
        max_input_age=3600.0,
        **lossless,
    )
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
    clock = ros.node.create_publisher(Clock, '/clock', 10)
    ticks = []  # [ns] published

    def tick() -> None:
        """Once the node's /clock reader is matched: 10 s before the bag's start up to it in 0.25 s
        steps, then the start, held.  The node's 1 Hz status timer fires at each second on the way,
        so a first report lost before /diagnostics matched cannot stall the wait (a clock held at
        the start fires it once: it timed out in a loaded newcomer run).
        """
        if clock.get_subscription_count() >= 1:
            ticks.append(min(START_NS, START_NS + (len(ticks) - 40) * 250_000_000))
            clock.publish(Clock(clock=Time(sec=ticks[-1] // 10**9, nanosec=ticks[-1] % 10**9)))

    # the node runs on the bag's clock: its status timer fired on it, and the start was published
    ros.spin_until(
        lambda: (
            ticks[-1:] == [START_NS]
            and any(
                stamp_key(d) >= START_NS - 10 * 10**9
                for d in diagnostics
                if model_statuses([d], namespace)
            )
            and ros.node.count_publishers(f'{namespace}/force_estimate') >= 1
        ),
        30,
        "model_node on the bag's clock",
        every=tick,
        diagnose=lambda: processes.output(node),
    )
    player = processes.start(
        [
            sys.executable,
            '-m',
            'pma_model_ros.cli',
            'bag',
            'play',
            str(bag),
            '--clock',
            '--wait-for-subscribers',
            '20',
            '--delay',
            '2',
        ]
    )  # both ends matched; the recorded force, which model_node does not read, is played too
    ros.spin_until(
        lambda: player.poll() is not None and len(estimates) >= len(offline),
        60,
        f"the replay's last estimate (offline: {len(offline)})",
        diagnose=lambda: (
            f'got {len(estimates)}\n' + processes.output(player) + processes.output(node)
        ),
    )
    assert player.returncode == 0, processes.output(player)
    assert f'bag play: no subscriber on {namespace}/force; played all the same' in (
        processes.output(player)
    )
    replayed = [(stamp_key(e), e.wrench.force.x) for e in estimates]
    # every input answered, and the last from both last inputs, as offline
    assert len(replayed) == len(offline), [  # what the node counted
        (s.message, status_values(s)) for s in model_statuses(diagnostics, namespace)[-1:]
    ]
    assert replayed[-1][0] == offline[-1][0]
    assert replayed[-1][1] == pytest.approx(offline[-1][1], rel=1e-12, abs=1e-9)
    # DDS orders messages per topic, not across topics: on a loaded machine the node may take a
    # muscle_state after the next ticks' pressures (or the reverse), and each input is answered
    # with the newest other one it has. So each estimate, live and offline, is the model's force
    # at one recorded pressure and one recorded length, stamped with the newer of the two.
    pairs = _pair_forces(bag, config, namespace)
    for name, answers in (('offline', offline), ('replayed', replayed)):
        found = [
            np.isclose(pairs[stamp], force, rtol=1e-12, atol=1e-9).any()  # scalar vs vector: ulps
            for stamp, force in answers
        ]
        assert all(found), f'{name}: {found.count(False)} estimates of no recorded pair'


def _pair_forces(bag: Path, config: Path, namespace: str) -> dict[int, np.ndarray]:
    """For each recorded stamp [ns] t: the force of the file's model at every pair of a recorded
    pressure and length whose newer stamp is t (pressure t with a length up to t, or the reverse).
    """
    settings = node_settings(read_parameters(config))
    assert settings.config.pressure_reference == 'absolute'
    inputs = {'pressure': [], 'muscle_state': []}
    for topic, _, message in read(bag, [f'{namespace}/{name}' for name in inputs]):
        stamp = message.header.stamp.sec * 10**9 + message.header.stamp.nanosec
        value = (
            message.fluid_pressure - settings.config.ambient_pressure
            if topic.endswith('/pressure')
            else message.position[0]
        )
        inputs[topic.rsplit('/', 1)[1]].append((stamp, value))
    (stamps, gauge), (length_stamps, length) = (map(list, zip(*v)) for v in inputs.values())
    assert stamps == length_stamps  # one pressure and one length per tick
    gauge, length = np.array(gauge), np.array(length)
    forces = settings.config.model.force(gauge[:, None], length[None, :]).force
    return {
        t: np.concatenate([forces[k, : k + 1], forces[: k + 1, k]]) for k, t in enumerate(stamps)
    }


def test_simulator_records_what_it_publishes(ros, processes, namespace, tmp_path):
    out = tmp_path / 'sim.db3'
    sim = processes.start(
        [
            sys.executable,
            '-m',
            'pma_model_ros.nodes.simulator_node',
            '--record',
            str(out),
            '--ros-args',
            '-r',
            f'__ns:={namespace}',
            '-p',
            'rate:=100.0',
            '-p',
            'seed:=3',
            '-p',
            'noise.force_std:=0.5',
        ]
    )
    forces = ros.collect(WrenchStamped, f'{namespace}/force', SENSOR_QOS)
    ros.spin_until(
        lambda: len(forces) >= 100,
        30,
        '100 force messages',
        diagnose=lambda: processes.output(sim),
    )
    assert not out.exists()  # written beside it until the node stops
    assert node_process.stop(sim) == 0, processes.output(sim)
    assert storage_of(out) == 'sqlite3'
    recorded = {}
    for topic, time_ns, msg in read(out):
        recorded.setdefault(topic, []).append((time_ns, msg))
    assert sorted(recorded) == [f'{namespace}/{t}' for t in ('force', 'muscle_state', 'pressure')]
    counts = {len(v) for v in recorded.values()}
    assert len(counts) == 1 and counts.pop() >= len(forces)
    by_stamp = {stamp_key(m): m.wrench.force.x for _, m in recorded[f'{namespace}/force']}
    assert all(by_stamp[stamp_key(f)] == f.wrench.force.x for f in forces)  # received: recorded
    assert all(t == stamp_key(m) for msgs in recorded.values() for t, m in msgs)  # log time: stamp
    summary = estimate_bag(
        out,
        node_settings(read_parameters(CONFIGS['DMSP-10-250'])),
        tmp_path / 'est',
        progress=False,
    )
    assert summary.estimates >= 2 * len(forces) - 1
