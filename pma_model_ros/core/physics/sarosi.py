"""The Sárosi DMSP-10-100 parameters, converted to SI (the shipped muscle of them:
:func:`~pma_model_ros.core.files.shipped_data.dmsp_10_100_hysteresis`).

Sárosi eq. 3 is F = (a1 p + a2) exp(a3 k) + a4 k p + a5 p + a6 with p in bar and
the contraction k in percent.  With p = P / 1e5 (P in Pa) and k = 100 kappa it is
Martens & Boblan eq. 19 with c0 = a1 1e-5, c1 = a2, c2 = 100 a3, d0 = a4 1e-3,
d1 = a5 1e-5, d2 = a6.
"""

from __future__ import annotations

import numpy as np

#: [Pa] The highest pressure of the measurements the parameters were fitted to (Tables 2 and 4:
#: 0-600 kPa).
IDENTIFIED_PRESSURE = 600e3


def to_si(published: list[float]) -> np.ndarray:
    """Sárosi [a1..a6] (bar, percent) -> eq. 19 [c0, c1, c2, d0, d1, d2] (Pa, fraction)."""
    a1, a2, a3, a4, a5, a6 = published
    return np.array([a1 * 1e-5, a2, 100 * a3, a4 * 1e-3, a5 * 1e-5, a6])
