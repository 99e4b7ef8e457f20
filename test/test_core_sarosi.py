"""The Sárosi DMSP-10-100 parameters (core/physics/sarosi.py, its muscle in
core/files/shipped_data.py): the SI conversion against eq. 3 in published units, and the two
hysteresis branches.
"""

import math

import pytest

from pma_model_ros.core.files.shipped_data import (
    dmsp_10_100_hysteresis,
    shipped_force_map,
    shipped_spec,
)
from pma_model_ros.core.identification.protocols import domain_of
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.models import force_raw, get_model
from pma_model_ros.core.physics.sarosi import to_si


def test_sarosi_si_conversion_matches_published_units():
    published = [-13.05, 215.62, -0.35, -3.08, 100.49, -215.22]  # Table 2: p in bar, k in %
    a1, a2, a3, a4, a5, a6 = published
    spec, fmap = shipped_spec('DMSP-10-100'), shipped_force_map('DMSP-10-250')
    got = {}
    for p_bar, k_pct in ((6.0, 0.0), (3.0, 10.0), (6.0, 20.0)):
        expected = (a1 * p_bar + a2) * math.exp(a3 * k_pct) + a4 * k_pct * p_bar + a5 * p_bar + a6
        L = spec.nominal_length * (1 - k_pct / 100)
        got[p_bar, k_pct] = force_raw(
            get_model('sarosi'), to_si(published), spec, domain_of(fmap), p_bar * 1e5, L
        )
        assert got[p_bar, k_pct] == pytest.approx(expected, rel=1e-12)
    # These units make physical sense: about 525 N at 6 bar and L0, near zero at 20 % contraction.
    assert got[6.0, 0.0] == pytest.approx(525.0, abs=1.0)
    assert 0 < got[6.0, 20.0] < 25


def test_hysteresis_branches():
    muscle = dmsp_10_100_hysteresis()
    up, down, unknown = (muscle.force(6e5, 0.09, rate) for rate in (0.01, -0.01, None))
    assert float(up.force) > float(unknown.force) > float(down.force) > 0
    assert float(unknown.force) == pytest.approx((float(up.force) + float(down.force)) / 2)
    assert unknown.flags == Flag.BRANCH_UNKNOWN and up.flags == down.flags == Flag.OK
