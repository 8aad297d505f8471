"""Build the followbot distribution: the follower and the MuJoCo simulator."""

from glob import glob

from setuptools import setup

package_name = 'followbot'

setup(
    name=package_name,
    version='0.1.0',
    packages=['followbot', 'followbot_sim'],
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/models', glob('models/*.xml')),
        ('share/' + package_name + '/config', glob('config/*.yaml') + glob('config/*.xml')),
    ],
    # A ROS package lists only setuptools here: on a Jazzy system rclpy, the messages,
    # NumPy, OpenCV and MuJoCo come from package.xml via rosdep. Without ROS, the pinned
    # PyPI wheels come from requirements.txt.
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='followbot developers',
    maintainer_email='followbot@example.com',
    description='Camera-guided yellow-line follower and its headless MuJoCo simulator.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'follower = followbot.follower_node:main',
            'calibrate = followbot.calibrate:main',
            'replay = followbot.replay:main',
            'sim = followbot_sim.sim_node:main',
            'followbot = followbot_sim.launcher:main',
            'scorecard = followbot_sim.scorecard:main',
            'benchmark = followbot_sim.benchmark:main',
        ],
    },
)
