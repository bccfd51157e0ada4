from setuptools import find_packages, setup

package_name = 'pam_bag'

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
    description=('MCAP bags for the PAM stack: the bag library, bag_record, bag_play, '
                 'pam-bag-info, pam-bag-recover.'),
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'bag_record = pam_bag.entry_points:bag_record',
            'bag_play = pam_bag.entry_points:bag_play',
            'pam-bag-info = pam_bag.entry_points:pam_bag_info',
            'pam-bag-recover = pam_bag.entry_points:pam_bag_recover',
        ],
    },
)
