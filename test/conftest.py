"""Shared fixtures."""
from pathlib import Path

import pytest

from pma_model_ros.core.param_file import muscle_model, read_parameters

REPO = Path(__file__).resolve().parents[1]
CONFIGS = {"DMSP-10-250": REPO / "config" / "dmsp_10_250.yaml", "DMSP-20-300": REPO / "config" / "dmsp_20_300.yaml",
           "DMSP-10-100": REPO / "config" / "dmsp_10_100.yaml"}


@pytest.fixture
def martens_10_250():
    return muscle_model(read_parameters(CONFIGS["DMSP-10-250"]), "martens")
