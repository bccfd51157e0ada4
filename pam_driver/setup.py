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
            'sim_node = pam_driver.sim_node:main',
            'profile_player = pam_driver.profile_player:main',
            'driver_node = pam_driver.driver_node:main',
            'pam-emulator = pam_driver.emulator:main',
            'bag_record = pam_driver.bag_record:main',
            'bag_play = pam_driver.bag_play:main',
            'pam-bag-info = pam_driver.bag_info:main',
            'pam-bag-recover = pam_driver.bag_recover:main',
        ],
    },
)
