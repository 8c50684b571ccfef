# Copyright 2026 qrm_ros developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

from glob import glob

from setuptools import find_packages, setup

package_name = 'qrm_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    # PEP 561: the package is typed; type checkers read its hints once it is installed.
    # The front doors' stubs (core, its kinematics and dynamics, analysis) are read at run
    # time by lazy_loader as well as by type checkers.
    package_data={package_name: ['py.typed', 'testing/examples/*.mcap',
                                 'testing/examples/*.yaml', '*/__init__.pyi',
                                 '*/*/__init__.pyi']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config',
         glob('config/*.yaml') + glob('config/*.rviz') + glob('config/*.json')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/urdf', glob('urdf/*.urdf')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'mcap', 'rosbags', 'matplotlib', 'tqdm',
                      'numba', 'pyyaml', 'foxglove-sdk', 'lazy_loader'],
    extras_require={
        'test': ['pytest', 'flake8', 'pydocstyle', 'mcap-ros2-support', 'pyyaml',
                 'yourdfpy', 'mypy', 'sympy'],
        # MP4 animations (qrm_animate -o OUT.mp4): a bundled ffmpeg
        'video': ['imageio-ffmpeg'],
        'dask': ['dask[distributed]'],
    },
    zip_safe=False,  # PEP 561: type checkers cannot read a package out of a zipped egg
    maintainer='qrm_ros developers',
    maintainer_email='qrm-ros-dev@example.com',
    description='Modified quick-return (shaper) mechanism: kinematics, ROS 2 node, '
                'MCAP recorder and TR/SR analysis.',
    license='Apache-2.0',
    entry_points={
        # The test kit's fixtures (qrm_ros.testing) in every pytest run of an environment
        # that has the package.
        'pytest11': ['qrm_ros = qrm_ros.testing.plugin'],
        'console_scripts': [
            'qrm_design = qrm_ros.cli.entry_points:qrm_design',
            'shaper_sim = qrm_ros.cli.entry_points:shaper_sim',
            'mcap_recorder = qrm_ros.cli.entry_points:mcap_recorder',
            'qrm_analyze = qrm_ros.cli.entry_points:qrm_analyze',
            'qrm_animate = qrm_ros.cli.entry_points:qrm_animate',
            'qrm_main = qrm_ros.cli.entry_points:qrm_main',
            'qrm_urdf = qrm_ros.cli.entry_points:qrm_urdf',
            'qrm_simulate = qrm_ros.cli.entry_points:qrm_simulate',
            'mcap_player = qrm_ros.cli.entry_points:mcap_player',
            'qrm_bridge = qrm_ros.cli.entry_points:qrm_bridge',
        ],
    },
)
