from glob import glob

from setuptools import find_packages, setup

package_name = 'island_mapping'

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
    entry_points={
        'console_scripts': [
            'island_builder_node = island_mapping.nodes.island_builder_node:main',
            'island_localizer_node = island_mapping.nodes.island_localizer_node:main',
            'topo_graph_server_node = island_mapping.nodes.topo_graph_server_node:main',
            'recorder_node = island_mapping.nodes.recorder_node:main',
            'islands = island_mapping.cli:main'
        ],
    },
)
