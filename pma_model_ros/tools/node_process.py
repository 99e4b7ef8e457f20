"""Start this package's nodes as separate processes and stop them cleanly (demo and tests)."""

from __future__ import annotations

from pathlib import Path
import signal
import subprocess
import sys
from typing import IO

NODES = ('model_node', 'simulator_node', 'joint_node', 'joint_simulator_node')


def command(
    node: str,
    namespace: str,
    params_file: str | Path | None = None,
    params: dict[str, object] | None = None,
) -> list[str]:
    """The command line of ``node`` in ``namespace`` with a params file and ``-p`` overrides."""
    if node not in NODES:
        raise ValueError(f'unknown node {node!r}; nodes: {", ".join(NODES)}')
    cmd = [
        sys.executable,
        '-m',
        f'pma_model_ros.nodes.{node}',
        '--ros-args',
        '-r',
        f'__ns:={namespace}',
    ]
    if params_file is not None:
        cmd += ['--params-file', str(params_file)]
    for name, value in (params or {}).items():
        cmd += ['-p', f'{name}:={value}']
    return cmd


def start(
    cmd: list[str], log: IO[str], env: dict[str, str] | None = None, cwd: str | Path | None = None
) -> subprocess.Popen:
    """Start ``cmd`` with stdout and stderr going to ``log``."""
    return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, text=True, env=env, cwd=cwd)


def stop(process: subprocess.Popen, timeout: float = 10.0) -> int:
    """SIGINT, wait up to ``timeout`` [s], then SIGKILL; the exit code (negative: killed by that
    signal).
    """
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode
