"""How much the long randomised tests draw: the property tests' full count of examples and the
30 s fuzz under ``CI=true`` (``.ci/run``); a quarter of the examples (at least 10) and half the
fuzz in a developer's run of ``scripts/test``.

Every example is derandomised: each count draws the same examples on every run and machine.
"""

from __future__ import annotations

import os

from hypothesis import settings

FULL = os.environ.get('CI') == 'true'  #: the full counts (CI)


def count(full: int) -> int:
    """The number of examples of a property whose full count is ``full``."""
    return full if FULL else max(full // 4, 10)


def examples(full: int, **options) -> settings:
    """Hypothesis settings of a property test: :func:`count` examples, derandomised, no deadline
    and no example database (a test draws the same examples on every machine).
    """
    return settings(
        max_examples=count(full), deadline=None, derandomize=True, database=None, **options
    )
