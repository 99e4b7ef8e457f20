"""The shipped muscle data (``core/data``): specs, measured force maps, Sárosi's tables."""

from __future__ import annotations

from importlib import resources

from .force_map import ForceMap, parse_force_map_csv
from .geometry import MuscleSpec
from .user_files import load_yaml_mapping

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
