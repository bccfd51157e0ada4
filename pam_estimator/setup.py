from glob import glob

from setuptools import find_packages, setup

package_name = 'pam_estimator'

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
    description='Sensor-less UKF for the antagonistic PAM joint and its ROS 2 node.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'ukf_node = pam_estimator.entry_points:ukf_node',
            'pam-evaluate = pam_estimator.entry_points:pam_evaluate',
            'pam-identify = pam_estimator.entry_points:pam_identify',
            'pam-calibration-bags = pam_estimator.entry_points:pam_calibration_bags',
        ],
    },
)
