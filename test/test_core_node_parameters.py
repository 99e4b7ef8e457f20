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
        ('ambient_pressure', [0.0, 101325.0, 2e5], [-1.0, 2.5e5, 5e6]),
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
