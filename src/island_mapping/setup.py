import os
import stat
from glob import glob

from setuptools import find_packages, setup
from setuptools.command.develop import develop
from setuptools.command.install import install

package_name = 'island_mapping'

BIN_WRAPPER = """#!/bin/sh
# `islands` on PATH after `colcon build && . install/setup.sh`: the console script itself is
# installed where `ros2 run island_mapping islands` looks (setup.cfg), which is not on PATH.
exec "$(dirname "$0")/../lib/island_mapping/islands" "$@"
"""


def _bin_wrapper(scripts_dir):
    """When the console scripts go to <prefix>/lib/island_mapping (colcon, setup.cfg), put an
    `islands` that runs them in <prefix>/bin, which colcon's setup.sh adds to PATH."""
    scripts_dir = os.path.normpath(scripts_dir)
    if not scripts_dir.endswith(os.path.join('lib', package_name)):
        return  # a wheel or a plain pip install: the scripts are on bin already
    bin_dir = os.path.join(os.path.dirname(os.path.dirname(scripts_dir)), 'bin')
    os.makedirs(bin_dir, exist_ok=True)
    path = os.path.join(bin_dir, 'islands')
    with open(path, 'w') as f:
        f.write(BIN_WRAPPER)
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)


class InstallWithBin(install):
    def run(self):
        super().run()
        _bin_wrapper(self.install_scripts)


class DevelopWithBin(develop):
    def run(self):
        super().run()
        _bin_wrapper(self.script_dir)


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Islands of Reliability maintainers',
    maintainer_email='islands@example.org',
    description=(
        'Islands of reliability (Simhon and Dudek): line models, localization, the '
        'distinctiveness measure, island building and the topological graph server.'
    ),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    cmdclass={'install': InstallWithBin, 'develop': DevelopWithBin},
    entry_points={
        'console_scripts': [
            'island_builder_node = island_mapping.nodes.island_builder_node:main',
            'island_localizer_node = island_mapping.nodes.island_localizer_node:main',
            'topo_graph_server_node = island_mapping.nodes.topo_graph_server_node:main',
            'recorder_node = island_mapping.nodes.recorder_node:main',
            'explorer_node = island_mapping.nodes.explorer_node:main',
            'islands = island_mapping.cli:main'
        ],
    },
)
