from glob import glob

from setuptools import find_packages, setup

package_name = 'pam_driver'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='PAM ROS maintainers',
    maintainer_email='maintainers@pam-ros.invalid',
    description=('What faces the PAM rig, real or simulated: driver_node, the DAQ protocol, '
                 'calibration, pam-emulator, sim_node.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sim_node = pam_driver.entry_points:sim_node',
            'driver_node = pam_driver.entry_points:driver_node',
            'pam-emulator = pam_driver.entry_points:pam_emulator',
        ],
    },
)
