"""Joint specs from ``ros__parameters`` (a YAML file or joint_node's ROS parameters; its parameter
tables are :mod:`~pma_model_ros.core.files.joint_node_parameters`').

Layout (SI units; ``config/example_joint.yaml``)::

    /**:
      ros__parameters:
        joints: [elbow]
        elbow:
          radius: [0.015]              # lever arm r(θ) = Σ radius[k] θ^k [m]; one entry: a pulley
          limits: [-1.0, 1.0]          # joint range [rad]
          muscles: [flexor, extensor]  # topic namespaces of the two muscles
          positive: flexor             # shortens for positive θ (REP-103: counter-clockwise)
          flexor: {file: dmsp_10_250.yaml, length_at_zero: 0.234}
          extensor:
            file: dmsp_10_250.yaml
            length_at_zero: 0.234
            model: hildebrandt         # overrides the file's
            hysteresis: {input: pressure, pressure_deadband: 10000.0}  # as model_node's
          # without file: the muscle inline, as a single-muscle parameter file's keys (muscle,
          # model, length_range, models, ...)

A muscle's ``file`` is a single-muscle parameter file (``config/dmsp_10_250.yaml``); a relative one
is found beside the joint file, or in ``config_dir`` if that is set (:func:`muscle_folder`, for
``pma-model joint`` and joint_node alike); keys beside ``file`` (e.g. ``model``) override the
file's.  A hysteresis muscle's ``hysteresis`` mapping says what its branch
follows in joint_node (:func:`~pma_model_ros.core.files.param_file.hysteresis_follow`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from .joint_node_parameters import JOINT_PARAMETERS
from .node_parameters import names_of
from .param_file import file_kind, hysteresis_follow, muscle_model, read_parameters
from .param_file import identification as muscle_identification
from .user_files import load_yaml_mapping, read_user_file
from ..hints import missing_key
from ..physics.hysteresis import Follow
from ..physics.joint import Joint, Transmission
from ..physics.muscle_model import MuscleModel


def joint(name: str, parameters: dict, base: Path) -> Joint:
    """One joint from its ``<name>:`` block (nested mapping); ValueError names the joint and the
    problem.
    """
    where = f"joint '{name}'"
    if not isinstance(parameters, dict):
        raise ValueError(f"{where}: no parameters under '{name}:'")
    for key in ('radius', 'limits', 'muscles', 'positive'):
        if key not in parameters:
            raise ValueError(
                f'{where}: {missing_key(key, parameters, names_of(JOINT_PARAMETERS))}'
            )
    radius = parameters.get('radius')
    radius = (
        [radius] if isinstance(radius, (int, float)) and not isinstance(radius, bool) else radius
    )
    limits, names, positive = (
        parameters.get('limits'),
        parameters.get('muscles'),
        parameters.get('positive'),
    )
    if not (isinstance(radius, list) and radius and all(_number(v) for v in radius)):
        raise ValueError(
            f'{where}: radius must be a list of numbers [m] (polynomial coefficients), got '
            f'{radius!r}'
        )
    if not (isinstance(limits, list) and len(limits) == 2 and all(_number(v) for v in limits)):
        raise ValueError(f'{where}: limits must be [min, max] in rad, got {limits!r}')
    if not (
        isinstance(names, list)
        and len(names) == 2
        and all(isinstance(n, str) and n for n in names)
        and names[0] != names[1]
    ):
        raise ValueError(f'{where}: muscles must be two different names, got {names!r}')
    if positive not in names:
        raise ValueError(
            f'{where}: positive must name the muscle that shortens for positive θ, one of '
            f'{names}, '
            f'got {positive!r}'
        )
    ordered = names if positive == names[0] else names[::-1]
    models, follows, zero = [], [], []
    for muscle in ordered:
        block = parameters.get(muscle)
        if not isinstance(block, dict):
            raise ValueError(f"{where}: no parameters under '{muscle}:'")
        try:
            model, follow = _muscle(block, base)
        except (ValueError, OSError) as err:
            raise ValueError(f"{where}, muscle '{muscle}': {err}") from None
        length = block.get('length_at_zero')
        if not (_number(length) and 0 < length <= 10):
            raise ValueError(
                f"{where}, muscle '{muscle}': length_at_zero must be a length in m, got {length!r}"
            )
        models.append(model)
        follows.append(follow)
        zero.append(float(length))
    return Joint(
        name,
        tuple(models),
        tuple(ordered),
        tuple(zero),
        Transmission(tuple(float(v) for v in radius)),
        (float(limits[0]), float(limits[1])),
        tuple(follows),
    )


def _muscle(block: dict, base: Path) -> tuple[MuscleModel, Follow]:
    """A muscle's model and what its hysteresis branch follows, from its block (by file or
    inline).
    """
    own = _muscle_parameters(block, base)
    return muscle_model(own), hysteresis_follow(own)


def _muscle_parameters(block: dict, base: Path) -> dict:
    """A muscle's ``ros__parameters``: its ``file``'s, with the block's own keys over them."""
    file = block.get('file') or ''
    own = {
        k: v
        for k, v in block.items()
        if k not in ('file', 'length_at_zero') and v not in (None, '')
    }
    if file:
        path = Path(file) if Path(file).is_absolute() else base / file
        own = read_parameters(path) | own
    return own


def identification(joint: Joint, parameters: dict, base: Path) -> dict[str, str]:
    """The identification results of ``joint``'s two muscles (as
    :func:`~pma_model_ros.core.files.param_file.identification`, each key after the muscle's name),
    from the joint file's ``ros__parameters`` (nested).
    """
    return {
        f'{muscle} {key}': value
        for muscle in joint.muscle_names
        for key, value in muscle_identification(
            _muscle_parameters(parameters[joint.name][muscle], base)
        ).items()
    }


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def joints(parameters: dict, base: Path) -> list[Joint]:
    """Every joint of ``parameters`` (nested ``ros__parameters``), names from its ``joints``
    list.
    """
    names = parameters.get('joints')
    if not names and {'muscle', 'muscles'} & set(parameters):
        what = 'several muscles' if file_kind(parameters) == 'muscles' else 'one muscle'
        raise ValueError(
            f"not a joint file (no 'joints:'): a parameter file of {what}, read by model_node "
            'and pma-model force; a joint file lists its joints (config/example_joint.yaml)'
        )
    if not (isinstance(names, list) and names and all(isinstance(n, str) and n for n in names)):
        raise ValueError(f'joints must be a non-empty list of joint names, got {names!r}')
    if len(set(names)) != len(names):
        raise ValueError(f'joints: duplicate names in {names}')
    result = [joint(name, parameters.get(name), base) for name in names]
    muscles = [m for j in result for m in j.muscle_names]
    if len(set(muscles)) != len(muscles):
        raise ValueError(f'two joints share a muscle name: {muscles}')
    return result


def muscle_folder(config_dir: str, joint_file: str | Path | None, default: Path) -> Path:
    """The folder of a joint file's relative muscle ``file``s, one rule for ``pma-model joint``
    and joint_node: ``config_dir`` if set; else the joint file's folder; else (joints given
    without a file, as parameters) ``default``, the package's shipped ``config/``.
    """
    if config_dir:
        return Path(config_dir)
    return Path(joint_file).resolve().parent if joint_file is not None else default


def joint_file_of(argv: Sequence[str]) -> Path | None:
    """The joint file of a node's command line: the last ``--params-file`` with ``joints:`` (rcl
    reads them in order, the last one wins); None if none has.
    """
    for path in reversed([p for o, p in zip(argv, argv[1:]) if o == '--params-file']):
        try:
            data = load_yaml_mapping(read_user_file(path, 'parameter file'), path)
        except ValueError:
            continue
        nodes = [v.get('ros__parameters') for v in data.values() if isinstance(v, dict)]
        if any(isinstance(n, dict) and 'joints' in n for n in nodes):
            return Path(path)
    return None


def load_joints(path: str | Path) -> list[Joint]:
    """The joints of a joint parameter file; relative muscle files are found by
    :func:`muscle_folder` (beside it, unless it sets ``config_dir``).
    """
    parameters = read_parameters(path)
    base = muscle_folder(parameters.get('config_dir') or '', path, Path(path).parent)
    try:
        return joints(parameters, base)
    except ValueError as err:
        raise ValueError(f'{path}: {err}') from None
