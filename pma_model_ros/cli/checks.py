"""What every command checks before any work: the outputs it may write (``--overwrite``) and the
numbers of the command line in their units; :class:`CliError`, a user error.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import Sequence

from ..core.hints import pressure_hint
from ..core.physics.geometry import STANDARD_ATMOSPHERE


class CliError(Exception):
    """A user error: printed as one line, exit code 2."""


def finite(name: str, value: float, low: float, high: float, unit: str, hint: str) -> float:
    """``value`` of the option ``name`` if it is finite and within [``low``, ``high``] ``unit``;
    else a CliError with ``hint``.
    """
    if not (math.isfinite(value) and low <= value <= high):
        raise CliError(f'{name} {value:g} is outside {low:g}..{high:g} {unit}; {hint}')
    return value


def gauge_pressure(name: str, value: float) -> float:
    """A gauge pressure [Pa] of the command line; refused below vacuum and where its magnitude
    says bar or kPa (no muscle works below 1 kPa).
    """
    finite(name, value, -1e7, 1e7, 'Pa', 'gauge pressure in Pa')
    if value < -STANDARD_ATMOSPHERE:
        raise CliError(
            f'{name} {value:g} Pa gauge is below vacuum (-{STANDARD_ATMOSPHERE:g} Pa gauge = 0 Pa '
            'absolute); gauge pressure = absolute - ambient'
        )
    if 0 < abs(value) < 1e3:
        raise CliError(
            f'{name} {value:g} Pa is below 1 kPa, no working pressure of a muscle: gauge '
            f'pressure in Pa; {pressure_hint(value)}'
        )
    return value


def refuse_existing(paths: Sequence[str | Path], what: str) -> None:
    """A CliError naming the first of ``paths`` that exists (outputs are overwritten only with
    ``--overwrite``).
    """
    for path in paths:
        if os.path.lexists(path):
            raise CliError(f'{what}: {path} exists; not overwriting it (--overwrite overwrites)')


#: What an output option names: a ``file``; a ``bag`` (a file or a directory, replaced whole); a
#: ``directory`` written into (created if missing; its files checked by the command).
OUTPUT_KINDS = ('file', 'bag', 'directory')

#: Options naming what a command reads: never one of its outputs, even with ``--overwrite``.
INPUT_OPTIONS = ('data', 'muscle', 'config', 'bag')


def add_overwrite_option(p: argparse.ArgumentParser, outputs: dict[str, str]) -> None:
    """``--overwrite``; ``outputs`` maps each output option to its kind (:data:`OUTPUT_KINDS`),
    checked by :func:`check_outputs` before the command runs.
    """
    p.add_argument('--overwrite', action='store_true', help='overwrite existing output files')
    p.set_defaults(outputs=outputs)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, each output the command could not write: in a missing directory,
    a directory where a file is named, an existing file without ``--overwrite``, a folder without
    write permission, or one of the command's inputs.
    """
    inputs = []
    for name in INPUT_OPTIONS:
        value = getattr(args, name, None)
        inputs += [Path(v) for v in (value if isinstance(value, list) else [value]) if v]
    for option, kind in getattr(args, 'outputs', {}).items():
        value = getattr(args, option[2:].replace('-', '_'))
        if value is None:
            continue
        path = Path(value)
        if kind == 'directory':
            if path.exists() and not path.is_dir():
                raise CliError(f'{option} {path} is not a directory')
            folder = next(p for p in (path, *path.absolute().parents) if p.exists())
        else:
            if kind == 'file' and path.is_dir():
                raise CliError(f'{option} {path} is a directory; name a file in it')
            if not args.overwrite:
                refuse_existing([path], option)
            folder = path.parent
            if not folder.is_dir():
                raise CliError(f'{option} {path}: no directory {folder}')
            for source in inputs:
                if path.exists() and source.exists() and os.path.samefile(path, source):
                    raise CliError(f'{option} {path} is an input of this command; name a new file')
        if not os.access(folder, os.W_OK | os.X_OK):
            raise CliError(f'{option} {path}: no permission to write in {folder}')
