"""The simulator's truth (core/simulation/truth.py, muscle.py's read_truth): any measured map, full
grid or not, an identified muscle, and the drift of the force over time.
"""

from pathlib import Path

import numpy as np
import pytest

from conftest import CONFIGS, REPO
from pma_model_ros.core.files.param_file import load_muscle
from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.identification.force_map import ForceMap
from pma_model_ros.core.simulation.muscle import defaults, read_truth, SimulatedMuscle
from pma_model_ros.core.simulation.truth import Drift, GroundTruth

SPEC = REPO / 'config' / 'muscles' / 'dmsp_10_250.yaml'
#: Two lengths, each a straight line in pressure over pressures of its own (no full grid):
#: 0.2 m: F = 1e-3 N/Pa (p - 150 kPa) measured at 200 and 300 kPa; 0.3 m: F = 1e-3 N/Pa p
#: measured at 100, 175, 200, 300 and 350 kPa.
HAND = ForceMap(
    [200e3, 300e3, 100e3, 175e3, 200e3, 300e3, 350e3],
    [0.2, 0.2, 0.3, 0.3, 0.3, 0.3, 0.3],
    [50.0, 150.0, 100.0, 175.0, 200.0, 300.0, 350.0],
)


def sparse_table_a2() -> ForceMap:
    """Table A2 (DMSP-10-250) as an isometric rig bins it: each length without its zero-force
    points and with every other pressure, the lengths alternating which (no pressure x length
    grid).
    """
    fmap = shipped_force_map('DMSP-10-250')
    keep = np.zeros(fmap.force.size, bool)
    for j, length in enumerate(fmap.lengths):
        (at,) = np.nonzero((fmap.length == length) & (fmap.force > 0))
        at = at[np.argsort(fmap.pressure[at])]
        keep[at[j % 2 :: 2]] = True
    return fmap.subset(keep)


def write_map(path: Path, fmap: ForceMap) -> Path:
    """``fmap`` as a force map CSV (pma-model fit --data's format) at ``path``."""
    path.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(
            f'{float(p)!r},{float(L)!r},{float(F)!r}\n'
            for p, L, F in zip(fmap.pressure, fmap.length, fmap.force)
        )
    )
    return path


def test_a_map_without_a_full_grid_is_a_truth_by_hand():
    """Straight rows stay straight (pchip of collinear points, the line beyond a row's own
    pressures, 0 N below its threshold), and with two lengths pchip across them is linear: every
    number here is the hand line's.
    """
    truth = GroundTruth(HAND)
    assert truth.force(HAND.pressure, HAND.length) == pytest.approx(HAND.force, abs=1e-9)
    for p, L, expected in (
        (175e3, 0.2, 25.0),  # below 0.2 m's first point, on its line
        (350e3, 0.2, 200.0),  # above its last point, on its line
        (100e3, 0.2, 0.0),  # its line is -50 N there: slack
        (250e3, 0.3, 250.0),  # between measured points
        (175e3, 0.25, (25.0 + 175.0) / 2),
        (350e3, 0.25, (200.0 + 350.0) / 2),
        (300e3, 0.275, 150.0 + 0.75 * 150.0),
    ):
        assert truth.force(p, L) == pytest.approx(expected, abs=1e-9), (p, L)
    np.testing.assert_array_equal(truth.pressures, [100e3, 175e3, 200e3, 300e3, 350e3])
    np.testing.assert_array_equal(truth.lengths, [0.2, 0.3])


def test_a_sparse_table_a2_keeps_its_points_and_never_overshoots_them():
    """Table A2 with half its points gone, differently per length: the kept points exactly; at a
    dropped point inside a length's kept pressures the force lies between its kept neighbours
    (pchip is monotone between data); never negative; monotone in pressure at every length.
    """
    full, sparse = shipped_force_map('DMSP-10-250'), sparse_table_a2()
    assert sparse.force.size < full.force.size / 2
    truth = GroundTruth(sparse)
    assert truth.force(sparse.pressure, sparse.length) == pytest.approx(sparse.force, abs=1e-9)
    checked = 0
    for length in sparse.lengths:
        row = sparse.length == length
        kept_p, kept_f = sparse.pressure[row], sparse.force[row]
        dropped = (full.length == length) & (full.pressure > kept_p.min())
        for p in full.pressure[dropped & (full.pressure < kept_p.max())]:
            if p in kept_p:
                continue
            low, high = kept_f[kept_p < p].max(), kept_f[kept_p > p].min()
            assert low <= truth.force(p, length) <= high, (p, length)
            checked += 1
    assert checked >= 10
    p = np.linspace(0, 7e5, 300)
    for length in np.linspace(0.19, 0.26, 29):
        f = truth.force(p, length)
        assert np.all(f >= 0) and np.all(np.diff(f) >= -1e-9), length


@pytest.mark.parametrize(
    'fmap, message',
    [
        (
            ForceMap([1e5, 2e5, 3e5], [0.2, 0.2, 0.2], [1, 2, 3]),
            'the truth needs at least 2 measured lengths, got 0.2 m only',
        ),
        (
            ForceMap([0, 1e5, 2e5], [0.2, 0.25, 0.25], [0, 10, 20]),
            'length 0.2 m has one measured pressure (0 Pa); the truth needs at least 2 per length',
        ),
    ],
)
def test_a_map_that_cannot_be_a_truth_says_why(fmap, message):
    with pytest.raises(ValueError) as err:
        GroundTruth(fmap)
    assert str(err.value) == message


def test_the_gain_ramps_from_1_to_its_value_then_stays():
    """0.85 over 60 s from 10 s: 1 until 10 s, 0.925 halfway (40 s), 0.85 at 70 s and after."""
    drift = Drift(gain=0.85, start=10.0, duration=60.0)
    np.testing.assert_allclose(
        drift.gain_at([0.0, 10.0, 40.0, 70.0, 1000.0]), [1, 1, 0.925, 0.85, 0.85], rtol=1e-15
    )
    step = Drift(gain=1.2, start=5.0)
    np.testing.assert_array_equal(step.gain_at([4.999, 5.0]), [1.0, 1.2])


def test_the_simulated_muscle_publishes_the_ramped_force():
    """The measured force (noise 0) is the truth times the gain at each instant."""
    base = {'trajectory': 'constant', 'initial_pressure': 4e5, 'length': 0.23}
    times = np.array([0.0, 10.0, 40.0, 70.0, 100.0])
    steady = SimulatedMuscle(defaults(**base), 0.0).run(times).force
    drifting = SimulatedMuscle(
        defaults(**base, drift__gain=0.85, drift__start=10.0, drift__duration=60.0), 0.0
    ).run(times)
    # at 0.23 m between Table A2's 22.8 N (0.219 m) and 101.5 N (0.234 m) at 402 kPa
    assert 22.8 < steady[0] < 101.5
    np.testing.assert_allclose(drifting.force / steady, [1, 1, 0.925, 0.85, 0.85], rtol=1e-12)


def test_a_second_map_takes_over_at_its_time(tmp_path):
    """drift.map_file at drift.at: before it the first map's force, from it on the second's
    (here the hand map with every force doubled).
    """
    first = write_map(tmp_path / 'first.csv', HAND)
    second = write_map(
        tmp_path / 'second.csv', ForceMap(HAND.pressure, HAND.length, 2 * HAND.force)
    )
    params = defaults(
        trajectory='constant',
        initial_pressure=300e3,
        length=0.3,
        map_file=str(first),
        spec_file=str(SPEC),
        drift__map_file=str(second),
        drift__spec_file=str(SPEC),
        drift__at=5.0,
    )
    muscle = SimulatedMuscle(params, 0.0)
    assert muscle.name == 'DMSP-10-250'  # the spec's
    forces = muscle.run(np.array([0.0, 4.999, 5.0, 9.0])).force
    np.testing.assert_allclose(forces, [300.0, 300.0, 600.0, 600.0], rtol=1e-12)


def test_an_identified_muscle_is_a_truth_over_its_identified_box():
    """params_file: the file's model as served, its length_range [0.198, 0.25] m and
    pressure_range [0, 650] kPa (config/dmsp_10_250.yaml) spanning the trajectories.
    """
    name, truth = read_truth(defaults(params_file=str(CONFIGS['DMSP-10-250'])))
    model = load_muscle(CONFIGS['DMSP-10-250'])
    assert name == 'DMSP-10-250'
    np.testing.assert_array_equal(truth.pressures, [0.0, 650e3])
    np.testing.assert_array_equal(truth.lengths, [0.198, 0.25])
    p, L = np.array([1e5, 3e5, 6e5]), np.array([0.2, 0.23, 0.25])
    np.testing.assert_array_equal(truth.force(p, L), model.force(p, L).force)
    # its max force: at the top pressure and longest length (Table A2: 542.5 N measured there)
    assert truth.max_force == pytest.approx(542.5, rel=0.05)


@pytest.mark.parametrize(
    'given, message',
    [
        ({'map_file': 'm.csv'}, "parameters 'map_file' and 'spec_file' go together"),
        (
            {'map_file': 'missing.csv', 'spec_file': str(SPEC)},
            "parameter 'map_file': force map file not found: missing.csv",
        ),
        (
            {'map_file': 'm.csv', 'spec_file': 'missing.yaml'},
            "parameter 'spec_file': muscle spec file not found: missing.yaml",
        ),
        (
            {'params_file': 'p.yaml', 'map_file': 'm.csv'},
            "parameters 'params_file' and 'map_file'/'spec_file' both name a truth: set one",
        ),
        ({'drift.params_file': 'missing.yaml'}, "parameter 'drift.params_file': "),
    ],
)
def test_a_truth_file_that_cannot_be_read_is_one_line_naming_the_parameter(
    tmp_path, monkeypatch, given, message
):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError) as err:
        SimulatedMuscle(defaults(**{k.replace('.', '__'): v for k, v in given.items()}), 0.0)
    assert str(err.value).startswith(message) and '\n' not in str(err.value)


def test_a_one_length_map_file_is_refused_naming_the_parameter_and_the_file(tmp_path):
    path = write_map(tmp_path / 'one.csv', ForceMap([1e5, 2e5, 3e5], [0.2] * 3, [1, 2, 3]))
    with pytest.raises(ValueError) as err:
        read_truth(defaults(map_file=str(path), spec_file=str(SPEC)))
    assert str(err.value) == (
        f"parameter 'map_file': {path}: the truth needs at least 2 measured lengths, got 0.2 m "
        'only'
    )
