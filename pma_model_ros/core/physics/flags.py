"""Per-sample status flags returned with every force and pressure value."""

from __future__ import annotations

import enum


class Flag(enum.IntFlag):
    """Bit flags; a result array carries one uint16 of these per sample."""

    OK = 0
    INVALID_INPUT = 1  #: non-finite input or a length the geometry cannot take; value is NaN
    #: length outside the lengths served (see Domain); served the nearest one
    LENGTH_OUT_OF_RANGE = 2
    #: gauge pressure outside the pressures served (see Domain); served the nearest one
    PRESSURE_OUT_OF_RANGE = 4
    CLIPPED = 8  #: the raw model pushes (F_raw < 0); served 0 N
    SATURATED = 16  #: wanted force needs a pressure outside [0, max_pressure]; served the bound
    BRANCH_UNKNOWN = 32  #: hysteresis model without a length-rate sign; served the branch mean
    #: outside the identified data, inside the physical envelope: the model's own value
    EXTRAPOLATED = 64
    #: gauge pressure below -VENTED_BAND: likely a gauge sensor read as absolute
    BELOW_AMBIENT = 128


def describe(flags: int) -> str:
    """Readable ``A|B`` form of one flag word, ``OK`` for none."""
    names = [f.name for f in Flag if f and flags & f]
    return '|'.join(names) if names else 'OK'
