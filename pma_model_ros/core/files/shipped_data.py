"""The shipped data: the muscle data inside the Python package (``core/data``: specs, measured
force maps, Sárosi's tables, and the DMSP-10-100 built from them) and the package's share directory
(``config/``, the parameter files).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
import sys

import numpy as np

from .user_files import load_yaml_mapping
from ..identification.force_map import ForceMap, parse_force_map_csv
from ..physics.geometry import MuscleSpec
from ..physics.models import Domain, get_model
from ..physics.muscle_model import MuscleModel
from ..physics.sarosi import IDENTIFIED_PRESSURE, to_si

PACKAGE = 'pma_model_ros'
SHIPPED_MUSCLES = {
    'DMSP-10-250': 'dmsp_10_250',
    'DMSP-20-300': 'dmsp_20_300',
    'DMSP-10-100': 'dmsp_10_100',
}
#: Muscles with a shipped measured force map (Martens & Boblan 2017, Tables A2 and A1).
MAPPED_MUSCLES = ('DMSP-10-250', 'DMSP-20-300')


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
    return parse_force_map_csv(_data_file(f'{_shipped_key(muscle)}_force_map.csv'), muscle)


def shipped_spec(muscle: str) -> MuscleSpec:
    """Spec of a shipped muscle by catalogue name."""
    key = _shipped_key(muscle)
    return MuscleSpec.from_mapping(load_yaml_mapping(_data_file(f'{key}.yaml'), f'{key}.yaml'))


def sarosi_tables() -> dict:
    """The Sárosi paper's published parameter tables for the DMSP-10-100 (as printed)."""
    return load_yaml_mapping(_data_file('sarosi_dmsp_10_100.yaml'), 'sarosi_dmsp_10_100.yaml')


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


def share_directory() -> Path:
    """The package's share directory (``config/``, ``package.xml``), from any working directory.

    Found through ament_index (``AMENT_PREFIX_PATH``: a sourced colcon workspace or ROS install);
    else, in an editable install (``scripts/setup``), the source tree, which holds the same files;
    else ``<sys.prefix>/share/pma_model_ros`` of a pip install.  FileNotFoundError if none has it.
    """
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(PACKAGE))
    except (ImportError, LookupError, OSError):  # not installed, not on the path, no prefix path
        pass
    source = Path(__file__).resolve().parents[3]
    for share in (source, Path(sys.prefix) / 'share' / PACKAGE):
        if (share / 'package.xml').is_file() and (share / 'config').is_dir():
            return share
    raise FileNotFoundError(
        f'the share directory of {PACKAGE} is not found: source the workspace that installs it '
        '(AMENT_PREFIX_PATH)'
    )
