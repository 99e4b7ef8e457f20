"""Braid geometry (eqs. 1-4) and muscle specs."""

import math

import numpy as np
import pytest

from pma_model_ros.core.files.shipped_data import SHIPPED_MUSCLES, shipped_spec
from pma_model_ros.core.files.user_files import read_spec_yaml
from pma_model_ros.core.physics import geometry as geo
from pma_model_ros.core.physics.geometry import MuscleSpec


@pytest.mark.parametrize('name', SHIPPED_MUSCLES)
def test_initial_state_is_consistent(name):
    spec = shipped_spec(name)
    # eq. 2 at L0 gives back D0, and eq. 4 equals the cylinder of eq. 1.
    assert geo.diameter(spec, spec.nominal_length) == pytest.approx(spec.inner_diameter, rel=1e-12)
    L = np.linspace(0.7, 1.0, 7) * spec.nominal_length
    assert geo.volume(spec, L) == pytest.approx(
        math.pi / 4 * geo.diameter(spec, L) ** 2 * L, rel=1e-12
    )


def test_slopes_are_derivatives():
    spec = shipped_spec('DMSP-10-250')
    L, h = np.linspace(0.19, 0.25, 5), 1e-7
    assert geo.volume_slope(spec, L) == pytest.approx(
        (geo.volume(spec, L + h) - geo.volume(spec, L - h)) / (2 * h), rel=1e-6
    )
    assert geo.diameter_slope(spec, L) == pytest.approx(
        (geo.diameter(spec, L + h) - geo.diameter(spec, L - h)) / (2 * h), rel=1e-6
    )


def test_dmsp_10_250_numbers():
    spec = shipped_spec('DMSP-10-250')
    assert spec.fiber_angle == pytest.approx(math.radians(28.6))
    assert geo.fiber_length(spec) == pytest.approx(0.25 / math.cos(math.radians(28.6)))
    assert geo.turns(spec) == pytest.approx(0.25 * math.tan(math.radians(28.6)) / (math.pi * 0.01))
    # The muscle's maximal contraction (about 25 %, Sec. 2) is where dV/dL = 0: L = L_F / sqrt(3).
    assert 1 - geo.fiber_length(spec) / math.sqrt(3) / 0.25 == pytest.approx(0.34, abs=0.01)


@pytest.mark.parametrize(
    'change, message',
    [
        ({'nominal_length': -0.25}, 'nominal_length'),
        ({'inner_diameter': 10.0}, 'inner_diameter must be in metres .* millimetres'),
        ({'membrane_thickness': 1.8}, 'membrane_thickness must be in metres .* millimetres'),
        ({'fiber_angle': 28.6}, r'fiber_angle .*; degrees\? multiply by pi/180'),
        # 1 rad = 57.3 deg, beyond arctan(sqrt 2) = 54.7 deg where 3 cos^2 - 1 = 0: no pull at L0
        ({'fiber_angle': 1.0}, r'fiber_angle 1 rad \(57.3 deg\) is at or beyond arctan'),
        ({'max_pressure': '8 bar'}, 'max_pressure'),
        # the Festo data sheet's 8 bar, in bar, kPa, MPa and psi
        ({'max_pressure': 8}, r'max_pressure .* got 8; bar\? 8 bar = 800000 Pa$'),
        ({'max_pressure': 800}, r'max_pressure .* got 800; kPa\? 800 kPa = 800000 Pa$'),
        ({'max_pressure': 0.8}, r'max_pressure .* got 0.8; MPa\? 0.8 MPa = 800000 Pa$'),
        ({'max_pressure': 116}, r'max_pressure .* got 116; psi\? 116 psi = 799792 Pa$'),
        ({'colour': 'black'}, "unknown key 'muscle.colour'$"),
    ],
)
def test_bad_specs_are_rejected(change, message):
    data = shipped_spec('DMSP-10-250').to_mapping() | change
    with pytest.raises(ValueError, match=message):
        MuscleSpec.from_mapping(data)


def test_a_misspelled_spec_key_is_named_once_with_the_right_one():
    data = shipped_spec('DMSP-10-250').to_mapping()
    data['nominal_lenght'] = data.pop('nominal_length')
    with pytest.raises(ValueError) as err:
        MuscleSpec.from_mapping(data)
    assert str(err.value) == (
        "unknown key 'muscle.nominal_lenght' (did you mean 'muscle.nominal_length'?)"
    )


def test_user_spec_yaml(tmp_path):
    path = tmp_path / 'mine.yaml'
    path.write_text(
        'name: MAS-20-400\nnominal_length: 0.4\ninner_diameter: 0.02\nmembrane_thickness: 0.0018\n'
        'fiber_angle: 0.4992\nmax_pressure: 600000\n'
    )
    assert read_spec_yaml(path).nominal_length == 0.4
    path.write_text('- just\n- a list\n')
    with pytest.raises(ValueError, match='mapping'):
        read_spec_yaml(path)


def test_the_braid_pull_is_the_ideal_cylinder_at_the_outer_diameter():
    """By hand at L0: pi 0.0136^2 / 4 = 1.45267e-4 m^2, (3 cos^2 - 1) / sin^2 (28.6 deg) =
    5.7434: 540.9 N at 650 kPa, where Table A2 measured 542.5 N.  DMSP-20-300 at 0.296 m: cos^2
    Theta = (0.296 / 0.3)^2 cos^2 Theta0 = 0.75044, D^2 = D0^2 sin^2 Theta / sin^2 Theta0: pi
    (0.0236 m)^2 / 4 x 1.08911 x 5.01395 x 675 kPa = 1612.4 N (Table A1: 1653.5 N).  Zero at full
    contraction.
    """
    spec = shipped_spec('DMSP-10-250')
    assert geo.braid_pull(spec, 0.25) * 650e3 == pytest.approx(540.87, abs=0.01)
    assert geo.braid_pull(shipped_spec('DMSP-20-300'), 0.296) * 675e3 == pytest.approx(
        1612.4, abs=0.05
    )
    assert geo.braid_pull(spec, geo.shortest_length(spec)) == pytest.approx(0, abs=1e-12)
