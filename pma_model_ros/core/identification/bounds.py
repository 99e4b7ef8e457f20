"""The parameters a fit left at a bound of its search, and what that says about the map.

A parameter at its bound is not identified by the map: the fit would have moved it further.  The
bounds of :data:`~pma_model_ros.core.physics.models.MODELS` keep the search finite; where one is a
limit of the search rather than of the physics, the line says so.
"""

from __future__ import annotations

import math

import numpy as np

from .force_map import ForceMap
from .protocols import BRANCH_MODEL
from ..physics.geometry import MuscleSpec
from ..physics.hysteresis import branch_name
from ..physics.models import get_model, Model

#: [-] A parameter within this share of its bound's magnitude (at least 1) lies at it.
_AT = 1e-9
#: Sárosi's DMSP-10-100 tables (Tables 1-4): c2 = 100 a3 [1 per unit contraction].
_SAROSI_C2 = (-41.0, -35.0)


def at_bounds(
    model: Model, theta: np.ndarray, spec: MuscleSpec, fmap: ForceMap, follow: str = 'length'
) -> list[str]:
    """One line per parameter of ``theta`` at a bound of ``model``'s search, with what it means
    on ``fmap`` (a hysteresis model: each branch by its model's bounds, named by the input its
    branches ``follow``).
    """
    if model.hysteresis:
        single = get_model(BRANCH_MODEL[model.name])
        n = single.n_params
        return [
            line
            for k, branch in enumerate((1.0, -1.0))
            for line in _lines(
                single,
                theta[k * n : (k + 1) * n],
                spec,
                fmap.subset(fmap.direction == branch),
                f' ({branch_name(follow, branch)})',
            )
        ]
    return _lines(model, theta, spec, fmap, '')


def _lines(model: Model, theta, spec: MuscleSpec, fmap: ForceMap, label: str) -> list[str]:
    lines = []
    for name, value, low, high in zip(model.param_names, theta, model.lower, model.upper):
        for bound in (low, high):
            if math.isfinite(bound) and abs(value - bound) <= _AT * max(1.0, abs(bound)):
                lines.append(
                    f'{name}{label} at its bound {bound:g}: the map does not identify it (the '
                    'fit would move it further); '
                    + (
                        _sarosi_c2(bound, spec, fmap)
                        if (model.name, name) == ('sarosi', 'c2')
                        else "its force is the bound's, not a measured value"
                    )
                )
    return lines


def _sarosi_c2(bound: float, spec: MuscleSpec, fmap: ForceMap) -> str:
    """What Sárosi's c2 (the rate of exp(c2 kappa), kappa = (L0 - L) / L0) at ``bound`` means:
    the term (c0 p + c1) exp(c2 kappa) is alive at the map's longest row alone (c2 < 0) or its
    shortest (c2 > 0), an offset of that row.
    """
    lengths = np.unique(fmap.length)[:: -1 if bound < 0 else 1]  # that row first
    kappa = (spec.nominal_length - lengths) / spec.nominal_length
    end, nxt = (f'{v:.4g} m' for v in lengths[:2])
    fall = math.exp(-abs(bound * (kappa[1] - kappa[0])))
    return (
        f'exp(c2 kappa) falls to {fall:.2g} from the {"longest" if bound < 0 else "shortest"} '
        f'row ({end}) to the next ({nxt}), so (c0 p + c1) exp(c2 kappa) fits that row alone, '
        'and the force between the two is no measured shape; the bound is a limit of the '
        f"search, not of the physics (Sárosi's DMSP-10-100: c2 {_SAROSI_C2[0]:g} to "
        f'{_SAROSI_C2[1]:g}): measure a row between them'
    )
