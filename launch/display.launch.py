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
"""
See the machine in RViz: shaper_sim, robot_state_publisher with the URDF, rviz2.

    ros2 launch qrm_ros display.launch.py [rviz:=false] [use_sim_time:=true]
        [params_file:=...] [urdf_file:=...] [rviz_config:=...]

robot_state_publisher and rviz2 come with a ROS installation (they are not on PyPI). The
shipped URDF is for the default geometry: for another one, write it with
``qrm_urdf -o my.urdf --crank-radius ...`` and pass ``urdf_file:=my.urdf``. The launch
imports sit inside generate_launch_description so that the file paths can be checked
without the launch packages.
"""

import os

from ament_index_python.packages import get_package_share_directory

PACKAGE = 'qrm_ros'
URDF_FILE = os.path.join('urdf', 'qrm_shaper.urdf')
RVIZ_FILE = os.path.join('config', 'shaper.rviz')
PARAMETERS_FILE = os.path.join('config', 'shaper.yaml')


def display_files():
    """Installed URDF, RViz configuration and parameter file, through the ament index."""
    share = get_package_share_directory(PACKAGE)
    return {'urdf_file': os.path.join(share, URDF_FILE),
            'rviz_config': os.path.join(share, RVIZ_FILE),
            'params_file': os.path.join(share, PARAMETERS_FILE)}


def _robot_state_publisher(context):
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    from launch_ros.parameter_descriptions import ParameterValue
    with open(LaunchConfiguration('urdf_file').perform(context)) as handle:
        description = handle.read()
    return [Node(package='robot_state_publisher', executable='robot_state_publisher',
                 output='screen',
                 parameters=[{'robot_description': ParameterValue(description, value_type=str),
                              'use_sim_time': LaunchConfiguration('use_sim_time')}])]


def generate_launch_description():
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.conditions import IfCondition
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    files = display_files()
    use_sim_time = LaunchConfiguration('use_sim_time')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=files['params_file'],
                              description='YAML parameter file for shaper_sim'),
        DeclareLaunchArgument('urdf_file', default_value=files['urdf_file'],
                              description='URDF of the machine (qrm_urdf writes one for any '
                                          'geometry)'),
        DeclareLaunchArgument('rviz_config', default_value=files['rviz_config'],
                              description='RViz configuration'),
        DeclareLaunchArgument('rviz', default_value='true', description='Start rviz2'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='Follow /clock instead of the system clock'),
        Node(package=PACKAGE, executable='shaper_sim', name='shaper_sim', output='screen',
             parameters=[LaunchConfiguration('params_file'), {'use_sim_time': use_sim_time}]),
        OpaqueFunction(function=_robot_state_publisher),
        Node(package='rviz2', executable='rviz2', output='screen',
             arguments=['-d', LaunchConfiguration('rviz_config')],
             parameters=[{'use_sim_time': use_sim_time}],
             condition=IfCondition(LaunchConfiguration('rviz'))),
    ])
