"""The launch files (launch/*.launch.py) start what exists, with arguments that reach the nodes.

launch and launch_ros are ROS packages, not installable from pip: where they import (a ROS
install, ``colcon test``) each file's launch description is built by them for real; everywhere
each file runs against stand-ins of their classes that record what the file asks of them, and the
records are checked against the package: executables (setup.py's entry points), managed nodes
launched as LifecycleNode, every launch configuration declared, ``autostart`` given to the node as
a bool, each default parameter file shipped and read by its node's reader.
"""

import ast
import importlib.util
from pathlib import Path
import sys
import types

import pytest

from conftest import REPO
from pma_model_ros.core.files.joint_file import load_joints
from pma_model_ros.core.files.param_file import read_parameters
from pma_model_ros.core.simulation.muscle import PARAMETERS as SIMULATOR_PARAMETERS

LAUNCH_FILES = sorted((REPO / 'launch').glob('*.launch.py'))
MANAGED = {'model_node', 'joint_node'}
#: Which shipped parameter file each node reads, and how it is read.
READERS = {'model_node': read_parameters, 'joint_node': load_joints}


class Recorded:
    """A stand-in of a launch class: its name and the arguments it was built with."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs

    def __repr__(self) -> str:
        return f'{type(self).__name__}{self.args}{self.kwargs}'


def stand_ins() -> dict[str, types.ModuleType]:
    """Modules ``launch``, ``launch_ros`` and their submodules, each class a :class:`Recorded`."""
    classes = {
        'launch': ['LaunchDescription'],
        'launch.actions': ['DeclareLaunchArgument'],
        'launch.substitutions': ['LaunchConfiguration', 'PathJoinSubstitution'],
        'launch_ros': [],
        'launch_ros.actions': ['LifecycleNode', 'Node'],
        'launch_ros.descriptions': ['ParameterValue'],
        'launch_ros.substitutions': ['FindPackageShare'],
    }
    modules = {}
    for name, members in classes.items():
        module = types.ModuleType(name)
        for member in members:
            setattr(module, member, type(member, (Recorded,), {}))
        modules[name] = module
    return modules


def described(path: Path) -> Recorded:
    """``generate_launch_description()`` of ``path``, run against the stand-ins."""
    saved = {name: sys.modules.get(name) for name in stand_ins()}
    sys.modules.update(stand_ins())
    try:
        spec = importlib.util.spec_from_file_location(path.stem.replace('.', '_'), path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.generate_launch_description()
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module


def walk(value):
    """Every :class:`Recorded` inside ``value`` (lists, dicts, arguments), depth first."""
    if isinstance(value, Recorded):
        yield value
        for item in (*value.args, *value.kwargs.values()):
            yield from walk(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from walk(item)
    elif isinstance(value, dict):
        for item in value.values():
            yield from walk(item)


def entry_points() -> set[str]:
    """The console scripts setup.py installs (``ros2 run pma_model_ros <name>``): its strings
    ``'<name> = <module>:<function>'``.
    """
    return {
        node.value.split(' = ')[0]
        for node in ast.walk(ast.parse((REPO / 'setup.py').read_text()))
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and ' = ' in node.value
    }


def test_there_are_the_documented_launch_files():
    assert [p.name for p in LAUNCH_FILES] == [
        'joint_node.launch.py',
        'model_node.launch.py',
        'simulator_demo.launch.py',
    ]


def test_setup_installs_the_launch_files():
    text = (REPO / 'setup.py').read_text()
    assert "('share/' + PACKAGE + '/launch', glob('launch/*.launch.py'))" in text


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda p: p.name)
def test_a_launch_file_starts_what_exists(path):
    description = described(path)
    assert type(description).__name__ == 'LaunchDescription'
    everything = list(walk(description))
    declared = {
        r.args[0]: r.kwargs.get('default_value')
        for r in everything
        if type(r).__name__ == 'DeclareLaunchArgument'
    }
    used = {r.args[0] for r in everything if type(r).__name__ == 'LaunchConfiguration'}
    assert used == set(declared), 'a configuration used but not declared, or declared unused'
    assert {'namespace', 'autostart', 'params_file'} <= set(declared)
    assert declared['autostart'] == 'true'  # as the nodes' own default

    nodes = [r for r in everything if type(r).__name__ in ('Node', 'LifecycleNode')]
    assert nodes
    for node in nodes:
        executable = node.kwargs['executable']
        assert node.kwargs['package'] == 'pma_model_ros'
        assert executable in entry_points(), executable
        assert node.kwargs['name'] == executable
        assert type(node.kwargs['namespace']).__name__ == 'LaunchConfiguration'
        assert node.kwargs['namespace'].args == ('namespace',)
        managed = type(node).__name__ == 'LifecycleNode'
        assert managed == (executable in MANAGED), f'{executable} launched as {type(node)}'
        parameters = node.kwargs['parameters']
        if managed:
            file, overrides = parameters
            assert file.args == ('params_file',)
            autostart = overrides['autostart']
            assert type(autostart).__name__ == 'ParameterValue'
            assert autostart.args[0].args == ('autostart',)
            assert autostart.kwargs == {'value_type': bool}
            default = declared['params_file']
            share, *relative = default.args[0]
            assert share.args == ('pma_model_ros',)  # FindPackageShare
            READERS[executable](REPO.joinpath(*relative))  # shipped, and its node's kind
        else:
            names = {spec.name for spec in SIMULATOR_PARAMETERS}
            for block in parameters:
                assert set(block) <= names, set(block) - names


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda p: p.name)
def test_the_docstring_launches_this_file(path):
    text = path.read_text()
    assert f'ros2 launch pma_model_ros {path.name}' in text


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda p: p.name)
def test_with_launch_ros_the_description_builds(path):
    """Where launch_ros imports (a ROS install): the file's description, built by it."""
    pytest.importorskip('launch_ros', reason='launch_ros is a ROS package (not on PyPI)')
    from launch.actions import DeclareLaunchArgument
    from launch_ros.actions import LifecycleNode, Node

    spec = importlib.util.spec_from_file_location(path.stem.replace('.', '_'), path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    entities = module.generate_launch_description().entities
    arguments = {e.name for e in entities if isinstance(e, DeclareLaunchArgument)}
    assert {'namespace', 'autostart', 'params_file'} <= arguments
    nodes = [e for e in entities if isinstance(e, Node)]
    assert sum(isinstance(e, LifecycleNode) for e in nodes) == 1
