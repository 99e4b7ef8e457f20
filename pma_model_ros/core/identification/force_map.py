"""Measured static force maps and their CSV files.

A force map is a set of points (gauge pressure [Pa], length [m], force [N]), and, for a
hysteresis model, the direction of each point (+1 lengthening or filling, -1 shortening or
venting). CSV files have the header ``pressure_pa,length_m,force_n`` (optionally ``,direction``);
lines starting with ``#`` are comments.  The paper's Tables A1/A2 ship
transcribed exactly (:mod:`~pma_model_ros.core.files.shipped_data`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
import io
import math
from pathlib import Path

import numpy as np

from ..files.user_files import read_user_file
from ..hints import length_hint, pressure_hint
from ..physics.geometry import STANDARD_ATMOSPHERE

COLUMNS = ('pressure_pa', 'length_m', 'force_n')
PRESSURE_CELL = 5e3  #: [Pa] pressure side of a :func:`cell_means` cell
LENGTH_CELL = 0.5e-3  #: [m] length side of a :func:`cell_means` cell
#: The optional fourth column: the hysteresis branch of each point, +1 or -1.
DIRECTION = 'direction'


@dataclass(frozen=True)
class ForceMap:
    """Measured points of one muscle, as flat arrays of equal length."""

    pressure: np.ndarray  #: gauge pressure [Pa]
    length: np.ndarray  #: muscle length [m]
    force: np.ndarray  #: measured tension [N]
    #: hysteresis branch of each point, +1 or -1 (None: not recorded)
    direction: np.ndarray | None = None
    #: the line of the file each point was read from, 1-based (None: not read from a file)
    line: np.ndarray | None = None
    #: [m] 0: lengths measured as they are; > 0: each length is the mean of a row of samples
    #: within a cell this wide (:func:`cell_means`), the row's samples up to one cell above it
    length_cell: float = 0.0

    def __post_init__(self) -> None:
        if self.direction is not None:
            d = np.asarray(self.direction, float).ravel()
            if d.size != np.asarray(self.force).size or not np.all(np.isin(d, (-1.0, 1.0))):
                raise ValueError(
                    'direction must be +1 (lengthening or filling) or -1 (shortening or venting) '
                    'for every point'
                )
            object.__setattr__(self, 'direction', d)
        p, L, F = (np.asarray(a, float).ravel() for a in (self.pressure, self.length, self.force))
        if not (p.size == L.size == F.size) or p.size < 3:
            raise ValueError(
                'a force map needs at least 3 points with pressure, length and force each'
            )
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(L)) and np.all(np.isfinite(F))):
            raise ValueError('force map has NaN or infinite values')
        if np.any(L <= 0) or np.any(L > 10):
            raise ValueError(
                f'length_m must be in metres (0 < L <= 10), got {L.min():g}..{L.max():g}'
                + (f'; {length_hint(L.max())}' if L.max() > 10 else '')
            )
        if np.any(p < 0):
            raise ValueError(
                f'pressure_pa must be gauge pressure >= 0 Pa (absolute - ambient), got {p.min():g}'
                + self._at(p == p.min())
                + ('; that is below vacuum' if p.min() < -STANDARD_ATMOSPHERE else '')
            )
        if np.any(p > 5e6):
            raise ValueError(
                f'pressure_pa must be gauge pressure in Pa (0..5e6), got {p.max():g}'
                + self._at(p == p.max())
            )
        if np.any(F < 0):
            raise ValueError(
                f'force_n must be >= 0 (a muscle only pulls), got {F.min():g}' + self._at(F < 0)
            )
        if F.max() <= 0:
            raise ValueError('a force map needs some positive force')
        for name, value in (('pressure', p), ('length', L), ('force', F)):
            object.__setattr__(self, name, value)

    def _at(self, points: np.ndarray) -> str:
        """`` at line N``: the file's line of the first of ``points`` (``''``: no file)."""
        if self.line is None:
            return ''
        return f' at line {int(np.asarray(self.line).ravel()[np.argmax(points)])}'

    @property
    def lengths(self) -> np.ndarray:
        """The distinct measured lengths [m], descending."""
        return np.unique(self.length)[::-1]

    @property
    def max_force(self) -> float:
        return float(self.force.max())

    def subset(self, mask: np.ndarray) -> 'ForceMap':
        return ForceMap(
            self.pressure[mask],
            self.length[mask],
            self.force[mask],
            None if self.direction is None else self.direction[mask],
            None if self.line is None else self.line[mask],
            self.length_cell,
        )


def cell_means(
    pressure: np.ndarray,
    length: np.ndarray,
    force: np.ndarray,
    direction: np.ndarray | None = None,
) -> ForceMap:
    """Samples (gauge pressure [Pa], length [m], force [N]; branch +1/-1, 0 unknown) as a map:
    averaged per :data:`PRESSURE_CELL` x :data:`LENGTH_CELL` (x branch) cell, negative forces
    (noise on a slack muscle) set to 0 N.  Each length cell is one row, as a measured map's: its
    points share the mean length of the row's samples.  The map carries each point's direction
    where every sample's branch is known.
    """
    p, L = np.asarray(pressure, float), np.asarray(length, float)
    F = np.maximum(np.asarray(force, float), 0.0)
    d = np.zeros(p.size) if direction is None else np.asarray(direction, float)
    _, row, in_row = np.unique(np.floor(L / LENGTH_CELL), return_inverse=True, return_counts=True)
    row = row.ravel()
    cells = np.column_stack([np.floor(p / PRESSURE_CELL), row, d])
    _, cell, count = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    cell = cell.ravel()
    p, F, d = (np.bincount(cell, weights=v) / count for v in (p, F, d))
    row_length = np.bincount(row, weights=L) / in_row
    L = np.empty(count.size)
    L[cell] = row_length[row]  # one value per row, not a mean per cell
    known = direction is not None and bool(np.all(d != 0))
    return ForceMap(p, L, F, d if known else None, length_cell=LENGTH_CELL)


def read_force_map_csv(path: str | Path) -> ForceMap:
    """Read a force map CSV (columns pressure_pa, length_m, force_n)."""
    return parse_force_map_csv(read_user_file(path, 'force map file'), str(path))


_SEPARATORS = (('semicolons', ';'), ('tabs', '\t'))  #: column separators named in errors


def parse_force_map_csv(text: str, source: str) -> ForceMap:
    """Parse the text of a force map CSV; ``source`` names it in errors."""
    numbered = [
        (number, ln)
        for number, ln in enumerate(text.splitlines(), start=1)
        if ln.strip() and not ln.lstrip().startswith('#')
    ]
    if not numbered:
        raise ValueError(
            f'{source}: the file is empty'
            + (' but for comments' if text.strip() else '')
            + f'; a force map CSV starts with the header {",".join(COLUMNS)}'
        )
    numbers, lines = zip(*numbered)
    for name, separator in _SEPARATORS:
        if separator in lines[0] and ',' not in lines[0]:
            raise ValueError(
                f'{source}: columns separated by {name}; a force map CSV separates them by commas '
                '(and writes decimals with a point)'
            )
    reader = csv.DictReader(io.StringIO('\n'.join(lines)))
    header = [f.strip() for f in reader.fieldnames or []]
    if header not in (list(COLUMNS), [*COLUMNS, DIRECTION]):
        raise ValueError(
            f'{source}: line {numbers[0]}: header must be {",".join(COLUMNS)}[,{DIRECTION}], '
            f'got {lines[0].strip()!r}'
        )
    columns = [raw for raw, name in zip(reader.fieldnames, header)]
    rows = []
    for number, line, row in zip(numbers[1:], lines[1:], reader):
        if None in row:  # more fields than the header: a decimal comma splits a number in two
            raise ValueError(
                f'{source}: line {number} has {len(columns) + len(row[None])} fields, the '
                f'header {len(columns)}; decimals are written with a point'
            )
        try:
            values = [float(row[c]) for c in columns]
        except (TypeError, ValueError):
            named = [name for name, separator in _SEPARATORS if separator in line]
            raise ValueError(
                f'{source}: line {number} is not {len(columns)} numbers: {line.strip()!r}'
                + (
                    f'; columns separated by {named[0]}, where commas separate them'
                    if named
                    else ''
                )
            ) from None
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f'{source}: line {number} has NaN or infinite values')
        rows.append(values)
    if not rows:
        raise ValueError(f'{source}: no data rows')
    data = np.array(rows)
    top = data[:, 0].max()
    if 0 < top < 1e3:
        raise ValueError(
            f'{source}: pressure_pa reaches only {top:g} Pa, no working pressure of a muscle: '
            f'gauge pressure in Pa; {pressure_hint(top)}'
        )
    try:
        return ForceMap(
            data[:, 0],
            data[:, 1],
            data[:, 2],
            data[:, 3] if data.shape[1] == 4 else None,
            np.array(numbers[1:], int),
        )
    except ValueError as err:
        raise ValueError(f'{source}: {err}') from None
