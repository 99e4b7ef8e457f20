"""What a force map and a spec are checked for before a fit (core/identification/map_checks.py):
no false alarm on the shipped maps, nor on their sensor zeros; the CLI's lines: test_cli.py.
"""

import numpy as np
import pytest

from pma_model_ros.core.files.shipped_data import shipped_force_map, shipped_spec
from pma_model_ros.core.identification.force_map import ForceMap
from pma_model_ros.core.identification.map_checks import check_against_spec, rest_threshold
from pma_model_ros.core.identification.protocols import check_fit_map

MUSCLES = ('DMSP-10-250', 'DMSP-20-300')


@pytest.mark.parametrize('muscle', MUSCLES)
@pytest.mark.parametrize(
    'pressure_zero, force_zero',
    [(0.0, 0.0), (20e3, 0.0), (-20e3, 0.0), (0.0, 10.0)],
)
def test_the_shipped_maps_pass_with_their_sensors_zeros(muscle, pressure_zero, force_zero):
    """Tables A1/A2 as measured, and read by a pressure sensor 20 kPa off either way (Table A1
    then starts at 55 kPa, no force there: inside the ambient band, but its rest-length row pulls
    from about 58 kPa, gauge) or a load cell 10 N off.
    """
    fmap = shipped_force_map(muscle)
    shifted = ForceMap(
        np.maximum(fmap.pressure + pressure_zero, 0), fmap.length, fmap.force + force_zero
    )
    check_fit_map(shifted, shipped_spec(muscle), folds=3)


def test_the_rest_length_threshold_is_bracketed_by_the_map():
    """Table A1 at 0.296 m: no force at 35 kPa, 54.9 N at 60 kPa; Table A2 at 0.25 m: none at
    5 kPa, 32.17 N at 68.75 kPa.  The threshold lies between.
    """
    a1, a2 = shipped_force_map('DMSP-20-300'), shipped_force_map('DMSP-10-250')
    assert 35e3 <= rest_threshold(a1, 0.296) <= 60e3
    assert 5e3 <= rest_threshold(a2, 0.25) <= 68.75e3


def test_absolute_pressures_are_named_whatever_the_first_step():
    """Table A1 + 101325 Pa starts at 136325 Pa (1.35 atm, above the ambient band) and still pulls
    nothing there at 0.296 m.
    """
    fmap = shipped_force_map('DMSP-20-300')
    absolute = ForceMap(fmap.pressure + 101325, fmap.length, fmap.force)
    with pytest.raises(ValueError, match='absolute - ambient'):
        check_against_spec(absolute, shipped_spec('DMSP-20-300'))
