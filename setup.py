"""Build script for pma_model_ros (ament_python; also pip-installable).

Only the pure-Python physics dependencies are listed in install_requires;
the ROS 2 dependencies (rclpy, message packages) are declared in package.xml.
"""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'pma_model_ros'

setup(
    name=PACKAGE,
    version='0.1.0',
    description=('Static force models of Festo pneumatic muscle actuators (DMSP/MAS) for ROS 2.'),
    license='Apache-2.0',
    maintainer='pma_model_ros maintainers',
    maintainer_email='maintainers@users.noreply.h-seed-b628454b.example',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={PACKAGE: ['core/data/*.csv', 'core/data/*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/muscles', glob('config/muscles/*.yaml')),
        ('share/' + PACKAGE + '/config/lifecycle', glob('config/lifecycle/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    python_requires='>=3.11',
    install_requires=['numpy', 'scipy', 'PyYAML'],
    extras_require={'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    entry_points={
        'console_scripts': [
            'pma-model = pma_model_ros.cli.main:main',
            'model_node = pma_model_ros.nodes.model_node:main',
            'simulator_node = pma_model_ros.nodes.simulator_node:main',
            'joint_node = pma_model_ros.nodes.joint_node:main',
            'joint_simulator_node = pma_model_ros.nodes.joint_simulator_node:main',
            'pma_composed = pma_model_ros.nodes.composed:main',
        ],
    },
)
