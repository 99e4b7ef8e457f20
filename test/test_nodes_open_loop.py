"""Open loop: simulator sweeps the whole DMSP-10-250 map; model_node's estimate vs the measured
force.

Both nodes are separate processes talking over DDS.  An estimate is matched to the
measured force of the same stamp (the last estimate of a stamp: the one computed once
both inputs of that instant were in).  The test collects until a full sweep is in and the
matched samples reach both pressure ends and every measured length.

Bounds, in % of the map's max force (542.5 N): the model's max error against the ground truth
(pchip between the measured points), computed here from the core, + NOISE_MARGIN

* near a measured length (|L - L_map| <= 0.25 mm): over that window (0.33 % at 0.198 m,
  4.58 % at 0.25 m, where the map's own points give the model's ``err``, 4.20 %);
* everywhere: over the whole map (7.71 %, between the 0.234 and 0.25 m curves).

The node reads every input however long it waited (``max_queue_delay``): the last estimate of a
stamp is then the one computed from both inputs of that stamp.  Skipping to the newest input
under load is test_nodes_faults.py's.
"""

from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest
from sensor_msgs.msg import FluidPressure, JointState

from conftest import CONFIGS
from node_messages import AMBIENT, RELIABLE_QOS, SENSOR_QOS, stamp_key
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.simulation.muscle import GroundTruth

pytestmark = pytest.mark.ros

NOISE = {'noise.pressure_std': 200.0, 'noise.length_std': 2e-5, 'noise.force_std': 0.5}
#: Sensor noise: sigma 0.5 N force + 200 Pa * <= 0.9 N/kPa + 0.02 mm * <= 16 N/mm, about 0.6 N
#: (0.11 %); 1 % is 9 sigma.
NOISE_MARGIN = 1.0
LENGTH_WINDOW = 0.25e-3  # [m]
SWEEP_PERIOD = 6.0  # [s] pressure triangle; the length triangle has period 2 s


def model_gap_to_truth(model, truth, around: float | None = None) -> float:
    """Max |model - ground truth| over a dense (pressure, length) grid [% of max force]: the whole
    map, or the lengths within LENGTH_WINDOW of ``around`` [m].
    """
    lo, hi = truth.lengths[0], truth.lengths[-1]
    if around is not None:
        lo, hi = max(lo, around - LENGTH_WINDOW), min(hi, around + LENGTH_WINDOW)
    p, L = np.meshgrid(
        np.linspace(truth.pressures[0], truth.pressures[-1], 80),
        np.linspace(lo, hi, 80),
        indexing='ij',
    )
    return (
        float(np.max(np.abs(model.force(p, L).force - truth.force(p, L)))) / truth.max_force * 100
    )


def matched(forces, estimates, states, pressures) -> np.ndarray:
    """Rows (length [m], gauge [Pa], measured force [N], estimate [N]) of the stamps all four
    topics carry, up to 0.2 s before the last estimate (the last estimate of each stamp: the one
    computed once both inputs of that instant were in).
    """
    if not estimates:
        return np.empty((0, 4))
    estimate = {stamp_key(e): e.wrench.force.x for e in estimates}
    length = {stamp_key(s): s.position[0] for s in states}
    gauge = {stamp_key(p): p.fluid_pressure - AMBIENT for p in pressures}
    last = stamp_key(estimates[-1]) - 0.2e9
    return np.array(
        [
            (length[k], gauge[k], f.wrench.force.x, estimate[k])
            for f in forces
            if (k := stamp_key(f)) in estimate and k in length and k in gauge and k <= last
        ]
    ).reshape(-1, 4)


def coverage_gaps(rows: np.ndarray, lengths: np.ndarray) -> list[str]:
    """What the matched samples still lack of the map: its pressure ends and a sample within
    LENGTH_WINDOW of each measured length (empty when they cover it).

    The length triangle turns at the shortest and the longest measured length; at 100 Hz the sample
    nearest a turn can lie 0.26 mm off it, and a dropped best-effort sample leaves the next one
    0.5 mm off, so one sweep need not cover them (CI once found none within 0.25 mm of 0.198 m).
    """
    L, p = rows[:, 0], rows[:, 1]
    gaps = [] if len(rows) and p.min() < 100e3 else ['a gauge pressure below 100 kPa']
    gaps += [] if len(rows) and p.max() > 550e3 else ['a gauge pressure above 550 kPa']
    return gaps + [
        f'a sample within {LENGTH_WINDOW * 1e3} mm of {g} m (nearest '
        f'{np.abs(L - g).min() * 1e3 if len(rows) else np.inf:.3f} mm off)'
        for g in lengths
        if not (len(rows) and (np.abs(L - g) <= LENGTH_WINDOW).any())
    ]


def test_estimate_follows_measured_force_over_the_map(ros, processes, namespace):
    params = read_parameters(CONFIGS['DMSP-10-250'])
    model = muscle_model(params)
    truth = GroundTruth(shipped_force_map('DMSP-10-250'))
    sim = processes.node(
        'simulator_node',
        namespace,
        trajectory='sweep',
        period=2.0,
        sweep_period=SWEEP_PERIOD,
        seed=3,
        **{k.replace('.', '__'): v for k, v in NOISE.items()},
    )
    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'], max_queue_delay=3600.0)
    topics = (
        ros.collect(WrenchStamped, f'{namespace}/force', SENSOR_QOS),
        ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS),
        ros.collect(JointState, f'{namespace}/muscle_state', SENSOR_QOS),
        ros.collect(FluidPressure, f'{namespace}/pressure', SENSOR_QOS),
    )
    forces, estimates = topics[:2]
    why = lambda: processes.output(sim) + processes.output(node)  # noqa: E731
    ros.spin_until(lambda: estimates, 30, 'a first force estimate', diagnose=why)
    first = stamp_key(estimates[0])
    gaps = ['a full sweep']

    def check() -> None:
        swept = stamp_key(estimates[-1]) - first > (SWEEP_PERIOD + 0.5) * 1e9
        gaps[:] = ([] if swept else ['a full sweep']) + coverage_gaps(
            matched(*topics), truth.lengths
        )

    ros.spin_until(
        lambda: not gaps,
        60,
        'samples over the whole map',
        every=check,
        period=0.5,
        diagnose=lambda: f'still lacking: {gaps}\n{why()}',
    )

    assert all(np.isfinite(e.wrench.force.x) for e in estimates)
    rows = matched(*topics)
    assert len(rows) > 200, f'only {len(rows)} matched samples'
    L, p, measured, estimated = rows.T
    error = np.abs(estimated - measured) / truth.max_force * 100

    gap = model_gap_to_truth(model, truth)
    worst = int(np.argmax(error))
    assert error.max() <= gap + NOISE_MARGIN, (
        f'max error {error.max():.2f} % at p={p[worst]:.0f} Pa L={L[worst]:.4f} m > {gap:.2f} + '
        f'{NOISE_MARGIN} %'
    )

    for grid_length in truth.lengths:
        near = np.abs(L - grid_length) <= LENGTH_WINDOW
        bound = model_gap_to_truth(model, truth, grid_length) + NOISE_MARGIN
        assert error[near].max() <= bound, (
            f'at L={grid_length} m: max error {error[near].max():.2f} % > {bound:.2f} %'
        )
