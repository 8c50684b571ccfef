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
"""Start shaper_sim with the installed config/shaper.yaml (`ros2 launch qrm_ros ...`)."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_parameters = os.path.join(get_package_share_directory('qrm_ros'), 'config',
                                      'shaper.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_parameters,
                              description='YAML parameter file for shaper_sim'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='Follow /clock instead of the system clock'),
        Node(package='qrm_ros', executable='shaper_sim', name='shaper_sim', output='screen',
             parameters=[LaunchConfiguration('params_file'),
                         {'use_sim_time': LaunchConfiguration('use_sim_time')}]),
    ])
