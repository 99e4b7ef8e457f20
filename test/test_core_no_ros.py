"""The core is numpy/scipy only: importing it (and the CLI) never loads rclpy."""

import subprocess
import sys


def test_core_imports_without_ros():
    code = (
        'import sys, pkgutil, importlib, pma_model_ros.core as c, pma_model_ros.cli.main\n'
        "for m in pkgutil.walk_packages(c.__path__, 'pma_model_ros.core.'): "
        'importlib.import_module(m.name)\n'
        "bad = [m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosidl_runtime_py', "
        "'sensor_msgs')]\n"
        'assert not bad, bad\n'
        "print(sum(m.startswith('pma_model_ros.core.') for m in sys.modules))"
    )
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout) > 30, 'every module of the core imported'
