from glob import glob

from setuptools import find_packages, setup

package_name = 'island_sim'

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
        'Simulated Nomad-200-like robot: line-segment worlds, sonar ring, drifting '
        'odometry and hall following.'
    ),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sonar_node = island_sim.nodes.sonar_node:main',
            'odometry_node = island_sim.nodes.odometry_node:main',
            'hall_follower_node = island_sim.nodes.hall_follower_node:main'
        ],
    },
)
