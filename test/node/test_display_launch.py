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
display.launch.py and the RViz configuration, as far as they can be checked without ROS's
launch, robot_state_publisher and rviz2 (not on PyPI): the installed launch file loads, the
files it names are installed, the RViz configuration shows what the node publishes.
"""

import importlib.metadata
import importlib.util
import os

from ament_index_python.packages import get_package_share_directory
import pytest
import yaml

from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import (absolute_topic, LINKAGE_MARKERS_TOPIC,
                                       ROBOT_DESCRIPTION_TOPIC)
from qrm_ros.node.shaper_sim.shaper_parameters import PARAMETERS
from qrm_ros.recording.urdf_model import BASE_LINK, urdf_text


def _installed_launch_module():
    path = os.path.join(get_package_share_directory('qrm_ros'), 'launch', 'display.launch.py')
    spec = importlib.util.spec_from_file_location('display_launch', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_installed_launch_file_loads_and_names_installed_files():
    files = _installed_launch_module().display_files()
    with open(files['urdf_file']) as handle:
        assert handle.read() == urdf_text(kin.Geometry.paper())
    for name in ('rviz_config', 'params_file'):
        assert os.path.isfile(files[name]), files[name]


def test_launched_executable_is_installed():
    scripts = {entry.name for entry in importlib.metadata.entry_points(group='console_scripts')}
    assert 'shaper_sim' in scripts


def test_launch_description_builds_where_ros_launch_is_installed():
    pytest.importorskip('launch_ros')
    description = _installed_launch_module().generate_launch_description()
    arguments = {a.name for a in description.get_launch_arguments()}
    assert {'params_file', 'urdf_file', 'rviz_config', 'rviz', 'use_sim_time'} <= arguments


def test_rviz_configuration_shows_the_model_and_the_markers_in_the_nodes_frame():
    path = os.path.join(get_package_share_directory('qrm_ros'), 'config', 'shaper.rviz')
    with open(path) as handle:
        config = yaml.safe_load(handle)
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == PARAMETERS['frame_id'].default
    assert PARAMETERS['frame_id'].default == BASE_LINK
    displays = {d['Class']: d for d in manager['Displays']}
    model = displays['rviz_default_plugins/RobotModel']
    assert model['Description Source'] == 'Topic'
    assert model['Description Topic']['Value'] == ROBOT_DESCRIPTION_TOPIC
    # robot_state_publisher latches the description: the display must ask for it so.
    assert model['Description Topic']['Durability Policy'] == 'Transient Local'
    markers = displays['rviz_default_plugins/MarkerArray']
    assert markers['Topic']['Value'] == absolute_topic(LINKAGE_MARKERS_TOPIC)
