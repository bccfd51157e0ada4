from setuptools import find_packages, setup

package_name = 'pam_model'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['data/*.yaml', 'data/*.csv']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='PAM ROS maintainers',
    maintainer_email='maintainers@pam-ros.invalid',
    description=('Antagonistic PAM joint model (Shin et al. 2021): physics, valve map, metrics, '
                 'profiles.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'pam-simulate = pam_model.cli.entry_points:pam_simulate',
            'pam-kappa = pam_model.cli.entry_points:pam_kappa',
        ],
    },
)
