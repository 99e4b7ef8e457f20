"""The Sárosi DMSP-10-100 parameters, converted to SI.

Sárosi eq. 3 is F = (a1 p + a2) exp(a3 k) + a4 k p + a5 p + a6 with p in bar and
the contraction k in percent.  With p = P / 1e5 (P in Pa) and k = 100 kappa it is
Martens & Boblan eq. 19 with c0 = a1 1e-5, c1 = a2, c2 = 100 a3, d0 = a4 1e-3,
d1 = a5 1e-5, d2 = a6.
"""

from __future__ import annotations

import numpy as np

from .models import Domain, get_model
from .muscle_model import MuscleModel
from .shipped_data import sarosi_tables, shipped_spec

#: [Pa] The highest pressure of the measurements the parameters were fitted to (Tables 2 and 4:
#: 0-600 kPa).
IDENTIFIED_PRESSURE = 600e3


def to_si(published: list[float]) -> np.ndarray:
    """Sárosi [a1..a6] (bar, percent) -> eq. 19 [c0, c1, c2, d0, d1, d2] (Pa, fraction)."""
    a1, a2, a3, a4, a5, a6 = published
    return np.array([a1 * 1e-5, a2, 100 * a3, a4 * 1e-3, a5 * 1e-5, a6])


def dmsp_10_100_hysteresis(
    upper: str = 'table2_upper_0_600kpa', lower: str = 'table4_lower_0_600kpa'
) -> MuscleModel:
    """DMSP-10-100 with Sárosi's upper/lower branches (default: Tables 2 and 4, 0-600 kPa).

    Identified on 0-600 kPa and 0-25 % contraction; no held-out data judge its extrapolation (the
    single-branch Sárosi model misses the DMSP-10-250's L0 by 1,065 % held out), so it does not
    extrapolate.
    """
    tables = sarosi_tables()
    theta = np.concatenate([to_si(tables[upper]), to_si(tables[lower])])
    return MuscleModel(
        shipped_spec('DMSP-10-100'),
        get_model('sarosi_hysteresis'),
        theta,
        Domain(*tables['length_range'], IDENTIFIED_PRESSURE),
    )
