"""Reading the files a user names: bounded size, UTF-8, YAML mappings, muscle specs."""

from __future__ import annotations

from pathlib import Path
import stat

import yaml

from ..physics.geometry import MuscleSpec

#: Largest user file read [bytes]: far above any force map or parameter file, far below a memory
#: problem.
MAX_FILE_BYTES = 16 * 1024 * 1024


def read_user_file(path: str | Path, what: str) -> str:
    """The UTF-8 text of the one regular file a user named (no search path, no includes); a
    leading byte-order mark (spreadsheet exports write one) is not part of the text.

    ValueError for a missing path, a directory, device or FIFO, a file over
    :data:`MAX_FILE_BYTES`, or bytes that are not UTF-8.
    """
    path = Path(path)
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ValueError(f'{what} not found: {path}') from None
    except OSError as err:
        raise ValueError(f'{what} {path}: {err.strerror}') from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f'{what} {path} is not a regular file')
    if info.st_size > MAX_FILE_BYTES:
        raise ValueError(
            f'{what} {path} is {info.st_size} bytes, over the {MAX_FILE_BYTES}-byte limit'
        )
    try:
        return path.read_bytes().decode('utf-8-sig')
    except UnicodeDecodeError:
        raise ValueError(f'{what} {path} is not UTF-8 text') from None
    except OSError as err:
        raise ValueError(f'{what} {path}: {err.strerror}') from None


def load_yaml_mapping(text: str, source: str) -> dict:
    """Parse YAML with the safe loader and require a mapping at the top."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ValueError(f'{source}: not valid YAML ({str(err).splitlines()[0]})') from None
    if not isinstance(data, dict):
        raise ValueError(
            f'{source}: expected a YAML mapping at the top, got {type(data).__name__}'
        )
    return data


def read_spec_yaml(path: str | Path) -> MuscleSpec:
    """Read a user's muscle spec YAML (keys of :class:`MuscleSpec`, SI units).

    A ROS parameter file (``<node>: ros__parameters:``) is refused with the spec file to use
    instead: the shipped ``muscles/<name>.yaml`` beside it if there is one.
    """
    data = load_yaml_mapping(read_user_file(path, 'muscle spec file'), str(path))
    nodes = [v for v in data.values() if isinstance(v, dict) and 'ros__parameters' in v]
    if nodes:
        raise ValueError(
            f'{path} is a ROS parameter file, not a muscle spec; {_spec_hint(path, nodes[0])}'
        )
    try:
        return MuscleSpec.from_mapping(*((data['muscle'],) if 'muscle' in data else (data, '')))
    except ValueError as err:
        raise ValueError(f'{path}: {err}') from None


def _spec_hint(path: str | Path, node: dict) -> str:
    """Where the spec of the muscle of a ROS parameter file is: a file beside it, or its keys."""
    muscle = (node.get('ros__parameters') or {}).get('muscle')
    name = muscle.get('name') if isinstance(muscle, dict) else None
    spec = Path(path).parent / 'muscles' / f'{str(name).lower().replace("-", "_")}.yaml'
    if name and spec.is_file():
        return f'the spec of its muscle {name} is {spec}'
    return (
        f'a spec file holds {", ".join(MuscleSpec.__dataclass_fields__)} '
        '(e.g. config/muscles/dmsp_10_250.yaml)'
    )
