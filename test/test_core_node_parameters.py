"""The one parameter table of model_node: docs/nodes.md shows it, the core and the node apply
the same ranges.
"""

import pytest

from conftest import CONFIGS, REPO
from pma_model_ros.core.files.node_parameters import markdown_table, PARAMETERS, SPECS
from pma_model_ros.core.runtime.engine import Config


def test_docs_table_is_the_schema():
    assert markdown_table() in (REPO / 'docs' / 'nodes.md').read_text(encoding='utf-8'), (
        "docs/nodes.md's parameter table differs from core/files/node_parameters.py; paste:\n"
        + markdown_table()
    )


@pytest.mark.parametrize(
    'name, inside, outside',
    [
        # Everest's summit 33.7 kPa (West 1999) to the sea-level record 108.48 kPa (WMO)
        ('ambient_pressure', [33.7e3, 101325.0, 108.48e3], [0.0, -1.0, 2.5e5, 5e6]),
        ('max_input_age', [1e-3, 0.1, 3600.0], [0.0, 5e-4, 4000.0]),
    ],
)
def test_core_checks_the_table_ranges(martens_10_250, name, inside, outside):
    for value in inside:
        Config(martens_10_250, **{name: value})
    for value in outside + [float('nan')]:
        with pytest.raises(ValueError, match=name):
            Config(martens_10_250, **{name: value})


def test_node_declares_each_row_with_its_range_and_flags(private_node):
    from pma_model_ros.nodes.model_node import ModelNode

    node = private_node(ModelNode, '--params-file', CONFIGS['DMSP-10-250'])
    names = [p.name for p in PARAMETERS if '<' not in p.name and p.name != 'executor']
    for spec, described in zip([SPECS[n] for n in names], node.describe_parameters(names)):
        ranges = [(r.from_value, r.to_value) for r in described.floating_point_range]
        assert ranges == ([spec.limits] if spec.limits else []), spec.name
        assert described.read_only == spec.read_only and described.description.startswith(
            spec.description
        )


@pytest.mark.parametrize(
    'value, unit',
    # one standard atmosphere, 101325 Pa, in each unit (ISO 80000-4: 1 bar = 1e5 Pa, 1 hPa =
    # 100 Pa; 1 psi = 6894.757 Pa)
    [(1.01325, 'bar'), (101.325, 'kPa'), (14.696, 'psi'), (1013.25, 'hPa'), (0.101325, 'MPa')],
)
def test_an_ambient_pressure_in_another_unit_is_named(value, unit):
    """A bar or kPa ambient pressure read as Pa gauged a 4 bar reading as about 5 bar: refused,
    naming the unit it looks like and the value in Pa.
    """
    with pytest.raises(ValueError, match='ambient_pressure') as refused:
        SPECS['ambient_pressure'].check(value)
    hint = str(refused.value).rpartition('(')[2]
    assert hint.startswith(f'{unit}? ') and float(hint.split('= ')[1].split()[0]) == (
        pytest.approx(101325.0, rel=1e-4)
    )
