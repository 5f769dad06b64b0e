from glob import glob

from setuptools import find_packages, setup

package_name = 'island_msgs_py'

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
        'Shared data types of the islands-of-reliability map (islands, edges, control '
        'strategies) with their JSON and ROS message forms; planar geometry, ray casting and '
        'scan/odometry pairing shared by the simulator and the mapping packages.'
    ),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [],
    },
)
