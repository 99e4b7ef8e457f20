"""Hints for what a user got wrong: the known name closest to a misspelled one (difflib), for every
file a user writes, and the unit a bare number looks like, for a value refused in SI units.

Muscles work at gauge pressures of about 0.1..1 MPa and are 0.01..3 m long; a number far below a
pascal value or far above a metre value was written in another unit, and the hint names the one it
looks like, with the value converted: ``bar? 3 bar = 300000 Pa``.
"""

from __future__ import annotations

import difflib
import math
from typing import Iterable

#: (unit, Pa per unit, largest magnitude read as that unit): the bands a working pressure of
#: 0.1..1 MPa takes in each unit (MPa 0.1..1, bar 1..10, psi 14.5..145, kPa 100..1000), made
#: contiguous; 1..12 is bar (12 bar is above the rating of pneumatic muscles, 1.2 MPa too).
PRESSURE_UNITS = (
    ('MPa', 1e6, 1.0),
    ('bar', 1e5, 12.0),
    ('psi', 6894.757293168, 150.0),
    ('kPa', 1e3, math.inf),
)
#: (unit, Pa per unit) of barometers (an ambient pressure of 1013.25 hPa), tried after
#: :data:`PRESSURE_UNITS`.
BAROMETER_UNITS = (('hPa', 100.0),)
#: (unit, m per unit) of lengths written in another unit than metres.
LENGTH_UNITS = (('cm', 1e-2), ('mm', 1e-3))
#: [m] A length a muscle typically has, for lengths without a muscle to compare with.
TYPICAL_LENGTH = 0.3


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


def pressure_hint(magnitude: float, within: tuple[float, float] | None = None) -> str:
    """The unit a pressure ``magnitude`` below 1 kPa (a bare number) looks like, and the value in
    Pa: ``bar? 3 bar = 300000 Pa``.  With ``within`` [Pa] (e.g. the ambient pressures on Earth):
    the first unit of :data:`PRESSURE_UNITS` or :data:`BAROMETER_UNITS` in which it lands there;
    ``''`` where none does.
    """
    if within is None:
        unit, scale = next((u, s) for u, s, most in PRESSURE_UNITS if abs(magnitude) <= most)
    else:
        units = [(u, s) for u, s, *_ in (*PRESSURE_UNITS, *BAROMETER_UNITS)]
        landing = [(u, s) for u, s in units if within[0] <= magnitude * s <= within[1]]
        if not landing:
            return ''
        unit, scale = landing[0]
    return f'{unit}? {magnitude:g} {unit} = {magnitude * scale:.6g} Pa'


def length_hint(
    length: float,
    reference: float = TYPICAL_LENGTH,
    within: tuple[float, float] = (0.0, math.inf),
) -> str:
    """The unit in which ``length`` (a bare number, far above the metres of a muscle) lands nearest
    to ``reference`` [m] (the muscle's rest length where known) by ratio, among those where it
    lands ``within`` [m] (the lengths the caller takes), and the value in metres:
    ``cm? 23 cm = 0.23 m``; ``''`` where no unit lands within.
    """
    units = [u for u in LENGTH_UNITS if within[0] <= length * u[1] <= within[1]]
    if not units:
        return ''
    unit, scale = min(units, key=lambda u: abs(math.log(length * u[1] / reference)))
    return f'{unit}? {length:g} {unit} = {length * scale:.6g} m'
