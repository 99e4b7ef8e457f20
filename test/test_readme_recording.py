"""docs/cli.md's recording-to-fit commands, run verbatim: a simulated calibration run recorded by
simulator_node (over DDS, 75 s) that `pma-model fit --bag` fits.
"""

import re
import subprocess

import pytest

from conftest import REPO
from pma_model_ros.bags.calibrate import SIMULATOR_SETTINGS
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.identification.protocols import max_error_percent

pytestmark = pytest.mark.ros


def page_commands() -> str:
    """The sh block after docs/cli.md's sentence naming this test."""
    page = (REPO / 'docs' / 'cli.md').read_text(encoding='utf-8')
    after = page[page.index('`test/test_readme_recording.py` runs these two commands') :]
    return re.search(r'```sh\n(.*?)```', after, re.DOTALL).group(1)


def test_the_documented_recording_is_fitted(tmp_path):
    commands = page_commands()
    assert ' '.join(SIMULATOR_SETTINGS.split()) in ' '.join(commands.split())  # fit --bag's hint
    for name in ('scripts', '.venv', 'config'):  # the page's paths, relative to a clone
        (tmp_path / name).symlink_to(REPO / name)
    run = subprocess.run(
        ['bash', '-c', commands], cwd=tmp_path, capture_output=True, text=True, timeout=240
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert sorted(p.name for p in (tmp_path / 'run1').iterdir()) == ['metadata.yaml', 'run1.mcap']
    kept, samples = map(
        int, re.search(r'run1: (\d+) of (\d+) samples quasi-static', run.stdout).groups()
    )
    assert samples >= 6500 and kept > 0.6 * samples, run.stdout  # 100 Hz for about 70 s
    assert 'default model (the one fitted): martens' in run.stdout
    fmap = shipped_force_map('DMSP-10-250')  # the measured map, never seen by the fit
    fitted = muscle_model(read_parameters(tmp_path / 'run1.yaml'))
    error = max_error_percent(
        fmap.force, fitted.force(fmap.pressure, fmap.length).force, fmap.max_force
    )
    # docs/cli.md: 3.16 % at b486110 (runs give 3.16-5.05 %: the recording's timing varies);
    # test_bags_calibrate's bound for a bag's fit judged on the measured map
    assert error < 5.5, error
