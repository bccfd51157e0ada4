from glob import glob

from setuptools import find_packages, setup

package_name = 'pam_controller'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='PAM ROS maintainers',
    maintainer_email='maintainers@pam-ros.invalid',
    description='Sensor-less PI control of the antagonistic PAM joint, references, bring-up.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'pi_node = pam_controller.entry_points:pi_node',
            'reference_node = pam_controller.entry_points:reference_node',
            'pam-bringup = pam_controller.entry_points:pam_bringup',
            'tracking_report = pam_controller.entry_points:tracking_report',
        ],
    },
)
