"""Measured static force maps and shipped muscle data.

A force map is a set of points (gauge pressure [Pa], length [m], force [N]), and, for a
hysteresis model, the direction of each point (+1 lengthening or filling, -1 shortening or
venting). CSV files have the header ``pressure_pa,length_m,force_n`` (optionally ``,direction``);
lines starting with ``#`` are comments.  The paper's Tables A1/A2 ship transcribed exactly.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from importlib import resources
import io
import math
from pathlib import Path
import stat

import numpy as np
import yaml

from .muscle import MuscleSpec

COLUMNS = ('pressure_pa', 'length_m', 'force_n')
#: The optional fourth column: the hysteresis branch of each point, +1 or -1.
DIRECTION = 'direction'
#: Largest user file read [bytes]: far above any force map or parameter file, far below a memory
#: problem.
MAX_FILE_BYTES = 16 * 1024 * 1024
SHIPPED_MUSCLES = {
    'DMSP-10-250': 'dmsp_10_250',
    'DMSP-20-300': 'dmsp_20_300',
    'DMSP-10-100': 'dmsp_10_100',
}
#: Muscles with a shipped measured force map (Martens & Boblan 2017, Tables A2 and A1).
MAPPED_MUSCLES = ('DMSP-10-250', 'DMSP-20-300')


@dataclass(frozen=True)
class ForceMap:
    """Measured points of one muscle, as flat arrays of equal length."""

    pressure: np.ndarray  #: gauge pressure [Pa]
    length: np.ndarray  #: muscle length [m]
    force: np.ndarray  #: measured tension [N]
    direction: np.ndarray | None = (
        None  #: hysteresis branch of each point, +1 or -1 (None: not recorded)
    )

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
                f'length_m must be in metres (0 < L <= 10), got {L.min():g}..{L.max():g}; '
                'millimetres? divide by 1000'
            )
        if np.any(p < 0) or np.any(p > 5e6):
            raise ValueError(
                f'pressure_pa must be gauge pressure in Pa (0..5e6), got '
                f'{p.min():g}..{p.max():g}; '
                'bar? multiply by 1e5'
            )
        if np.any(F < 0):
            raise ValueError('force_n must be >= 0 (a muscle only pulls)')
        if np.unique(L).size < 2 or F.max() <= 0:
            raise ValueError('a force map needs at least two lengths and some positive force')
        for name, value in (('pressure', p), ('length', L), ('force', F)):
            object.__setattr__(self, name, value)

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
        )


def read_user_file(path: str | Path, what: str) -> str:
    """The UTF-8 text of the one regular file a user named (no search path, no includes).

    ValueError for a missing path, a directory, device or FIFO, a file over
    :data:`MAX_FILE_BYTES`, or bytes that are not UTF-8.
    """
    path = Path(path)
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ValueError(f'{what} not found: {path}') from None
    except OSError as err:
        raise ValueError(f'{what} {path}: {err.strerror}') from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f'{what} {path} is not a regular file')
    if info.st_size > MAX_FILE_BYTES:
        raise ValueError(
            f'{what} {path} is {info.st_size} bytes, over the {MAX_FILE_BYTES}-byte limit'
        )
    try:
        return path.read_bytes().decode('utf-8')
    except UnicodeDecodeError:
        raise ValueError(f'{what} {path} is not UTF-8 text') from None
    except OSError as err:
        raise ValueError(f'{what} {path}: {err.strerror}') from None


def read_force_map_csv(path: str | Path) -> ForceMap:
    """Read a force map CSV (columns pressure_pa, length_m, force_n)."""
    return _parse_csv(read_user_file(path, 'force map file'), str(path))


def _parse_csv(text: str, source: str) -> ForceMap:
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith('#')]
    reader = csv.DictReader(io.StringIO('\n'.join(lines)))
    header = [f.strip() for f in reader.fieldnames or []]
    if header not in (list(COLUMNS), [*COLUMNS, DIRECTION]):
        raise ValueError(
            f'{source}: header must be {",".join(COLUMNS)}[,{DIRECTION}], got {reader.fieldnames}'
        )
    columns = [raw for raw, name in zip(reader.fieldnames, header)]
    rows = []
    for number, row in enumerate(reader, start=2):
        try:
            values = [float(row[c]) for c in columns]
        except (TypeError, ValueError):
            raise ValueError(
                f'{source}: data row {number} is not {len(columns)} numbers: {row}'
            ) from None
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f'{source}: data row {number} has NaN or infinite values')
        rows.append(values)
    if not rows:
        raise ValueError(f'{source}: no data rows')
    data = np.array(rows)
    try:
        return ForceMap(
            data[:, 0], data[:, 1], data[:, 2], data[:, 3] if data.shape[1] == 4 else None
        )
    except ValueError as err:
        raise ValueError(f'{source}: {err}') from None


def _data_file(name: str) -> str:
    return resources.files('pma_model_ros.core').joinpath('data', name).read_text(encoding='utf-8')


def _shipped_key(muscle: str) -> str:
    if muscle not in SHIPPED_MUSCLES:
        raise ValueError(
            f'unknown shipped muscle {muscle!r}; shipped: {", ".join(SHIPPED_MUSCLES)}'
        )
    return SHIPPED_MUSCLES[muscle]


def shipped_force_map(muscle: str) -> ForceMap:
    """The paper's measured map of ``DMSP-10-250`` (Table A2) or ``DMSP-20-300`` (Table A1)."""
    if muscle not in MAPPED_MUSCLES:
        raise ValueError(f'no shipped force map for {muscle!r}; maps: {", ".join(MAPPED_MUSCLES)}')
    return _parse_csv(_data_file(f'{_shipped_key(muscle)}_force_map.csv'), muscle)


def load_yaml_mapping(text: str, source: str) -> dict:
    """Parse YAML with the safe loader and require a mapping at the top."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ValueError(f'{source}: not valid YAML ({str(err).splitlines()[0]})') from None
    if not isinstance(data, dict):
        raise ValueError(
            f'{source}: expected a YAML mapping at the top, got {type(data).__name__}'
        )
    return data


def shipped_spec(muscle: str) -> MuscleSpec:
    """Spec of a shipped muscle by catalogue name."""
    key = _shipped_key(muscle)
    return MuscleSpec.from_mapping(load_yaml_mapping(_data_file(f'{key}.yaml'), f'{key}.yaml'))


def read_spec_yaml(path: str | Path) -> MuscleSpec:
    """Read a user's muscle spec YAML (keys of :class:`MuscleSpec`, SI units)."""
    data = load_yaml_mapping(read_user_file(path, 'muscle spec file'), str(path))
    try:
        return MuscleSpec.from_mapping(data.get('muscle', data))
    except ValueError as err:
        raise ValueError(f'{path}: {err}') from None


def sarosi_tables() -> dict:
    """The Sárosi paper's published parameter tables for the DMSP-10-100 (as printed)."""
    return load_yaml_mapping(_data_file('sarosi_dmsp_10_100.yaml'), 'sarosi_dmsp_10_100.yaml')
