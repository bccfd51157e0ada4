from setuptools import find_packages, setup

package_name = 'pam_common'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='PAM ROS maintainers',
    maintainer_email='maintainers@pam-ros.invalid',
    description=('Shared node infrastructure of the PAM stack: node skeleton, parameter '
                 'tables, executors and stop signals, diagnostics, timing, stamps, topic names '
                 'and QoS.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [],
    },
)
