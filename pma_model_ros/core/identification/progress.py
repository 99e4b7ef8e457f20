"""Progress of long work on stderr, so that nothing that takes seconds is silent.

One plain call per finished or started item of a loop::

    from pma_model_ros.core.identification.progress import step
    for k, model in enumerate(models, 1):
        step(k, len(models), f'DMSP-10-250: fitting {model}')

prints ``[k/n] what`` as one line on stderr.  On a terminal the line is rewritten in place until
``k == n`` (a counter, not a scrolling log); elsewhere (CI logs, pipes) each call is one line.
:class:`Meter` reports a count of many small items (messages of a bag) as ten steps.
Progress goes to stderr only: stdout stays the command's result (``reproduce --json | jq``).
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

#: [s] Work that ends sooner shows no :class:`Meter` lines.
QUIET = 1.0


def step(done: int, total: int, what: str, stream: TextIO | None = None) -> None:
    """Report ``[done/total] what`` on stderr (module docstring)."""
    out = sys.stderr if stream is None else stream
    line = f'[{done}/{total}] {what}'
    if out.isatty():
        out.write(f'\r\x1b[K{line}' + ('\n' if done >= total else ''))
    else:
        out.write(line + '\n')
    out.flush()


class Meter:
    """Progress of ``total`` small items: a :func:`step` line per tenth done, once the work has
    taken :data:`QUIET` seconds (short work stays silent).

    ``what`` names the work, e.g. ``'reading run1'``; :meth:`update` takes the count done so far.
    """

    def __init__(self, total: int, what: str, stream: TextIO | None = None) -> None:
        self.total, self.what, self.stream = max(int(total), 1), what, stream
        self._tenths, self._start = 0, time.monotonic()

    def update(self, done: int) -> None:
        tenths = min(10, 10 * done // self.total)
        if tenths > self._tenths and (self._tenths or time.monotonic() - self._start >= QUIET):
            self._tenths = tenths
            step(tenths, 10, f'{self.what}: {done:,} of {self.total:,}', self.stream)
