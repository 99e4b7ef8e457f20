"""The benchmarks' way to run ``pma-model`` in their own process (a helper module: bench/run
runs no ``_*.py``).
"""

from __future__ import annotations

import contextlib
import io

from pma_model_ros.cli.main import main as pma_model


def run(argv: list[str]) -> str:
    """``pma-model argv`` in this process; its standard output (exit code 0 asserted)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = pma_model(argv)
    if code != 0:
        raise SystemExit(f'pma-model {" ".join(argv)}: exit {code}')
    return out.getvalue()
