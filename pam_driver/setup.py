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
    description='Simulated antagonistic PAM rig (sim_node), drop-in for the hardware driver.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'sim_node = pam_driver.entry_points:sim_node',
            'profile_player = pam_driver.entry_points:profile_player',
            'driver_node = pam_driver.entry_points:driver_node',
            'pam-emulator = pam_driver.entry_points:pam_emulator',
            'bag_record = pam_driver.entry_points:bag_record',
            'bag_play = pam_driver.entry_points:bag_play',
            'pam-bag-info = pam_driver.entry_points:pam_bag_info',
            'pam-bag-recover = pam_driver.entry_points:pam_bag_recover',
        ],
    },
)
