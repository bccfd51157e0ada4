from setuptools import find_packages, setup

package_name = 'pam_controller'

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
    description=('Sensor-less PI control of the antagonistic PAM joint, references '
                 '(reference_node, profile_player), pam-robustness.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'pi_node = pam_controller.entry_points:pi_node',
            'reference_node = pam_controller.entry_points:reference_node',
            'profile_player = pam_controller.entry_points:profile_player',
            'pam-robustness = pam_controller.entry_points:pam_robustness',
        ],
    },
)
