"""Typos named: the known name closest to a misspelled one (difflib), for every file a user
writes.
"""

from __future__ import annotations

import difflib
from typing import Iterable


def did_you_mean(word: object, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the entry of ``known`` closest to ``word``, else ``''``."""
    close = difflib.get_close_matches(str(word), [str(k) for k in known], n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ''


def unknown_keys(mapping: dict, known: Iterable[str], where: str = '') -> list[str]:
    """One message per key of ``mapping`` not in ``known``, naming the closest known key;
    ``where`` prefixes the keys (``'elbow.'`` for a nested block).
    """
    known = list(known)
    return [
        f"unknown key '{where}{key}'{did_you_mean(f'{where}{key}', [where + k for k in known])}"
        for key in mapping
        if key not in known
    ]


def missing_key(key: str, mapping: dict, known: Iterable[str], where: str = '') -> str:
    """Why ``key`` is not in ``mapping``: an unknown key of it that is a misspelling of ``key``
    (named as :func:`unknown_keys` does), else ``'key' is missing``.
    """
    known = set(known)
    strangers = [str(k) for k in mapping if k not in known]
    close = difflib.get_close_matches(key, strangers, n=1, cutoff=0.6)
    if close:
        return f"unknown key '{where}{close[0]}' (did you mean '{where}{key}'?)"
    return f"'{where}{key}' is missing"
