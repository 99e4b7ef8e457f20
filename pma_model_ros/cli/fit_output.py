"""What ``pma-model fit`` prints and writes of every fit: the in-sample and nested held-out tables,
the rows worth measuring, the last line and the parameter file's legend.
"""

from __future__ import annotations

import math
from typing import Sequence, TYPE_CHECKING

import numpy as np

from ..core.identification.validation import fold_lengths, length_folds

if TYPE_CHECKING:  # imported where used: force and pressure need no identification (scipy)
    from ..core.identification.protocols import Fit

FILE_LEGEND = (
    'err: eq. 23 on the whole map [%]; cv_err: worst nested leave-one-length-out err [%] (the '
    'fit, calibration\nand choices included, re-run without each length); held_out: that err '
    'per held-out length.'
)


def worst(errors: np.ndarray) -> float:
    """The worst of per-fold errors [%], NaN if no fold could be judged."""
    return float(np.nanmax(errors)) if np.any(np.isfinite(errors)) else math.nan


def held_out_table(lengths, nested: dict[str, np.ndarray]) -> None:
    labels, w = length_headers(lengths), max(14, *(len(name) + 1 for name in nested))
    print(f'{"model":<{w}}' + ''.join(f'{label:>9}' for label in labels) + f'{"worst":>9}')
    for name, errors in nested.items():
        print(f'{name:<{w}}' + ''.join(f'{e:>9.2f}' for e in errors) + f'{worst(errors):>9.2f}')


def length_headers(lengths: Sequence[float]) -> list[str]:
    """Column headers of lengths [m]: 3 decimals, or as many more (up to 6) as make neighbouring
    ones differ (bands of a recording's lengths round alike at 3).
    """
    for digits in range(3, 7):
        texts = [f'{L:.{digits}f}' for L in lengths]
        if len(set(texts)) == len(texts):
            break
    return texts


def print_in_sample(objective: str, rows: dict[str, tuple[Fit, float]]) -> None:
    """The in-sample table of ``fit``: each model's fit and worst nested held-out err [%]."""
    print(
        f'\nin-sample err (eq. 23) [%], RMSE [N], R² ({objective}); held_out: worst nested '
        'leave-one-length-out err [%]\n(each length predicted by the whole fit, calibration '
        'included, re-run without it)'
    )
    w = max(14, *(len(name) + 1 for name in rows))
    print(f'{"model":<{w}}{"err":>8}{"rmse":>9}{"r2":>10}{"held_out":>10}')
    for name, (fit, cv_err) in rows.items():
        print(f'{name:<{w}}{fit.err:>8.2f}{fit.rmse:>9.3f}{fit.r2:>10.5f}{cv_err:>10.2f}')


def print_nested(fmap, nested: dict[str, np.ndarray]) -> None:
    """The nested held-out table of ``fit``: each model's err [%] per held-out length of
    ``fmap``.
    """
    print(
        '\nnested held-out err [%] per held-out length [m]'
        + (
            ' (groups of neighbouring lengths: their mean)'
            if len(length_folds(fmap)) < fmap.lengths.size
            else ''
        )
    )
    held_out_table(fold_lengths(fmap), nested)


def written_line(how: str, name: str, fit: Fit, nested: np.ndarray | None, out: str) -> str:
    """The last line of ``fit``: the written model's own figures, as its file serves them
    (``nested`` None: a map of two lengths, none held out between others).
    """
    held = 'no held-out figure' if nested is None else held_out_parts(nested)
    return (
        f'default model ({how}): {name}  err {fit.err:.3f} %  rmse {fit.rmse:.3f} N  r2 '
        f'{fit.r2:.5f}  {held}  -> {out}'
    )


#: [%, pp] An edge figure above EDGE_LARGE and above the interior one by EDGE_MARGIN is large.
EDGE_LARGE, EDGE_MARGIN = 5.0, 1.0


def rows_to_add(nested: np.ndarray, lengths: np.ndarray, spec, given: float | None = None) -> str:
    """What to measure when the fit's edge figure (nested held-out err per fold [%] at the fold
    ``lengths`` [m], longest first) is large against its interior one: the rows that make the
    lengths served there interpolation, the rest-length row (L0 of ``spec``, or the ``given`` L0
    [m] where the fit calibrated it) and the shortest working length; '' when it is not large.
    """
    from ..core.identification.selection import edge_err, interior_err
    from ..core.physics.geometry import shortest_length

    edge, interior = edge_err(nested), interior_err(nested)
    if not (edge > EDGE_LARGE and edge > interior + EDGE_MARGIN):
        return ''
    rest, longest, shortest = spec.nominal_length, float(lengths[0]), float(lengths[-1])
    side = 'longest' if nested[0] >= nested[-1] else 'shortest'
    # the longest row at the given L0, or within a calibrated L0's reach of it
    at_rest = any(abs(longest - L0) <= 0.005 * L0 for L0 in {rest, given or rest})
    calibrated = '' if f'{rest:.4g}' == f'{longest:.4g}' else f', L0 {rest:.4g} m as calibrated'
    return (
        f'beyond the measured lengths the fit errs by {edge:.2f} % (the {side}, predicted from '
        f'the others) against {interior:.2f} % between them; rows to measure: '
        + (
            f'one between {float(lengths[1]):.4g} and {longest:.4g} m (the rest-length row, '
            f'{longest:.4g} m{calibrated}, is measured: it is the edge, and a row beside it makes '
            'it less of an extrapolation)'
            if at_rest
            else f'the rest-length row at L0 {rest:.4g} m (not measured: the longest is '
            f'{longest:.4g} m)'
        )
        + ', and the shortest working length (the shortest is '
        f'{shortest:.4g} m; the braid pulls down to {shortest_length(spec):.4g} m)'
    )


def held_out_parts(nested: np.ndarray) -> str:
    """``held-out worst X % (between measured lengths Y %, beyond them Z %)``: the worst nested
    held-out err per fold [%] (longest first), on the lengths between the map's shortest and
    longest (interpolation) and on those two (extrapolation, as served there).
    """
    from ..core.identification.selection import edge_err, interior_err

    return (
        f'held-out worst {worst(nested):.2f} % (between measured lengths '
        f'{interior_err(nested):.2f} %, beyond them {edge_err(nested):.2f} %)'
    )
