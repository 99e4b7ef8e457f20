"""Bags of the simulated muscle written without ROS (bags/synthetic.py)."""

import numpy as np
import pytest

try:
    import rosbags  # noqa: F401
except ImportError:  # pip-only (a -pip rosdep key): colcon test on a ROS install without it
    pytest.skip(
        'needs rosbags, a pip-only library: pip install -r requirements-dev.txt',
        allow_module_level=True,
    )

from pma_model_ros.bags.bag_io import read
from pma_model_ros.bags.synthetic import record_simulation, START_NS
from pma_model_ros.core.files.shipped_data import shipped_force_map


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_rate_times_duration_messages_on_three_topics_stamped_on_the_grid(tmp_path, storage):
    """2 s at 50 Hz: 100 ticks, each a pressure, a muscle_state and a force.

    All three are stamped (header and log time) at START + k * 20 ms; a constant, noise-free held
    muscle reads what was asked.
    """
    bag = record_simulation(
        tmp_path / 'run',
        2.0,
        '/sim',
        storage,
        rate=50.0,
        trajectory='constant',
        length=0.23,
        initial_pressure=310e3,
        pressure_time_constant=0.0,
    )
    messages = list(read(bag))
    topics = {t for t, _, _ in messages}
    assert topics == {'/sim/pressure', '/sim/muscle_state', '/sim/force'}
    expected = [START_NS + k * 20_000_000 for k in range(100)]
    for name in topics:
        times = [ns for t, ns, _ in messages if t == name]
        stamps = [
            m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            for t, _, m in messages
            if t == name
        ]
        assert times == expected and stamps == expected, name
    pressures = [m.fluid_pressure for t, _, m in messages if t == '/sim/pressure']
    absolute = 101325.0 + 310e3  # ambient + 310 kPa gauge
    assert pressures == pytest.approx([absolute] * 100, abs=1e-6)
    lengths = [m.position[0] for t, _, m in messages if t == '/sim/muscle_state']
    assert lengths == pytest.approx([0.23] * 100)
    forces = np.array([m.wrench.force.x for t, _, m in messages if t == '/sim/force'])
    fmap = shipped_force_map('DMSP-10-250')  # 0.23 m: between Table A2's 0.219 and 0.234 m rows
    near = [fmap.force[(fmap.length == L) & (fmap.pressure == 310e3)][0] for L in (0.219, 0.234)]
    assert np.all((forces > min(near)) & (forces < max(near)))
