from glob import glob

from setuptools import find_packages, setup

package_name = 'pam_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config',
         glob('config/*.yaml') + glob('config/*.json') + glob('config/*.xml')),
        ('share/' + package_name + '/launch', glob('launch/*.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='PAM ROS maintainers',
    maintainer_email='maintainers@pam-ros.invalid',
    description='Bring-up of the PAM stack: pam-bringup, the stack description, launch files, '
                'bring-up parameter files, tracking_report, the demo (pam-demo).',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'pam-bringup = pam_bringup.entry_points:pam_bringup',
            'tracking_report = pam_bringup.entry_points:tracking_report',
            'pam-demo = pam_bringup.entry_points:pam_demo',
            'pam-foxglove = pam_bringup.entry_points:pam_foxglove',
            'pam_container = pam_bringup.entry_points:pam_container',
        ],
    },
)
