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
The Foxglove layout names only topics and fields that exist: in the message types the node
publishes, and in a recording made by the real node and recorder (the golden logs). It is the
one generated from the geometry, and its camera frames the machine as the URDF draws it.
"""

import json
import math
import os
import re

from ament_index_python.packages import get_package_share_directory
import numpy as np
import pytest
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
from rosbags.typesys.base import Nodetype

from qrm_ros.recording.bag_reader import open_run
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import (absolute_topic, DIAGNOSTICS_TOPIC, JOINT_NAMES,
                                       JOINT_STATE_TYPE, JOINT_STATES_TOPIC, LINKAGE_MARKERS_TOPIC,
                                       LINKAGE_MARKERS_TYPE, MACHINE_NAME, RAM_TWIST_TOPIC,
                                       ROBOT_DESCRIPTION_TOPIC, ROBOT_DESCRIPTION_TYPE,
                                       STROKE_PAIR_STATUS)
from qrm_ros.cli.qrm_urdf import main as qrm_urdf
from qrm_ros.recording.foxglove_layout import (foxglove_layout_text, machine_view_bounds,
                                               PANEL_ASPECT)
from qrm_ros.recording.urdf_model import BASE_LINK, write_urdf
from repo_paths import REPO_ROOT, TEST_DATA

GOLDEN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')
# What the node publishes, by recorded topic name.
PUBLISHED = {
    absolute_topic(JOINT_STATES_TOPIC): JOINT_STATE_TYPE,
    absolute_topic(RAM_TWIST_TOPIC): 'geometry_msgs/msg/TwistStamped',
    absolute_topic(DIAGNOSTICS_TOPIC): 'diagnostic_msgs/msg/DiagnosticArray',
    absolute_topic(LINKAGE_MARKERS_TOPIC): LINKAGE_MARKERS_TYPE,
    ROBOT_DESCRIPTION_TOPIC: ROBOT_DESCRIPTION_TYPE,  # written by the recorder beside them
}
_STEP = re.compile(r'\.([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?')


def _layout():
    path = os.path.join(get_package_share_directory('qrm_ros'), 'config',
                        'foxglove_layout.json')
    with open(path) as handle:
        return json.load(handle)


def _panels(kind):
    return {key: config for key, config in _layout()['configById'].items()
            if key.split('!')[0] == kind}


def _plot_paths():
    return [(path['value'], path['label']) for config in _panels('Plot').values()
            for path in config['paths']]


def _split(path):
    """'/joint_states.position[3]' -> ('/joint_states', [('position', 3)])."""
    topic = path[:path.index('.')]
    rest = path[len(topic):]
    steps = [(m.group(1), None if m.group(2) is None else int(m.group(2)))
             for m in _STEP.finditer(rest)]
    assert ''.join(m.group(0) for m in _STEP.finditer(rest)) == rest, f'unparsed: {path}'
    return topic, steps


def _resolve(fielddefs, typename, steps):
    """Walk field steps through message definitions; return the final base type."""
    node = (Nodetype.NAME, typename)
    for name, index in steps:
        assert node[0] == Nodetype.NAME, f'{name} is not a field of a message'
        fields = dict(fielddefs[node[1]][1])
        assert name in fields, f'{node[1]} has no field {name}'
        node = fields[name]
        if index is not None:
            assert node[0] in (Nodetype.SEQUENCE, Nodetype.ARRAY), f'{name} is not an array'
            node = node[1][0]
    assert node[0] == Nodetype.BASE, f'{steps} does not end on a number'
    return node[1][0]


def test_layout_panels_present_and_wired_to_our_names():
    layout = _layout()
    kinds = {key.split('!')[0] for key in layout['configById']}
    assert {'3D', 'Plot', 'DiagnosticSummary', 'DiagnosticStatusPanel'} <= kinds
    (scene,) = _panels('3D').values()
    assert scene['followTf'] == BASE_LINK
    assert sorted(scene['topics']) == sorted([absolute_topic(LINKAGE_MARKERS_TOPIC),
                                              ROBOT_DESCRIPTION_TOPIC])
    assert all(topic['visible'] for topic in scene['topics'].values())
    (status,) = _panels('DiagnosticStatusPanel').values()
    assert status['selectedHardwareId'] == MACHINE_NAME
    assert status['selectedName'] == STROKE_PAIR_STATUS
    # Every panel named in configById is placed in the layout tree, and vice versa.
    placed = re.findall(r'"([A-Za-z0-9 ]+![A-Za-z0-9]+)"', json.dumps(layout['layout']))
    assert sorted(placed) == sorted(layout['configById'])


def test_plot_paths_mean_what_their_labels_say():
    expected = {
        'ram position [m]': ('position', 'ram_joint'),
        'ram velocity [m/s]': ('velocity', 'ram_joint'),
        'flywheel speed [rad/s]': ('velocity', 'flywheel_joint'),
        'input speed [rad/s]': ('velocity', 'input_shaft_joint'),
        'input torque [N m]': ('effort', 'input_shaft_joint'),
    }
    paths = dict((label, value) for value, label in _plot_paths())
    assert sorted(paths) == sorted(expected)
    for label, (field, joint) in expected.items():
        assert paths[label] == (f'{absolute_topic(JOINT_STATES_TOPIC)}.{field}'
                                f'[{JOINT_NAMES.index(joint)}]')


def _layout_topics_and_paths():
    topics = {t for config in _panels('3D').values() for t in config['topics']}
    topics |= {config['topicToRender'] for kind in ('DiagnosticSummary', 'DiagnosticStatusPanel')
               for config in _panels(kind).values()}
    paths = [_split(value) for value, _ in _plot_paths()]
    return topics | {topic for topic, _ in paths}, paths


def test_every_topic_and_field_exists_in_the_published_types():
    typestore = get_typestore(Stores.ROS2_JAZZY)
    topics, paths = _layout_topics_and_paths()
    assert topics <= set(PUBLISHED), topics - set(PUBLISHED)
    for topic, steps in paths:
        assert _resolve(typestore.fielddefs, PUBLISHED[topic], steps) == 'float64'
        for _, index in steps:
            assert index is None or index < len(JOINT_NAMES)


def test_every_recorded_topic_and_field_exists_in_a_real_recording():
    """Against the schemas stored in a golden log (real node, real recorder)."""
    run = open_run(GOLDEN)
    recorded = run.topics()
    topics, paths = _layout_topics_and_paths()
    # The golden logs predate the node's markers and the recorded URDF.
    topics = {topic for topic in topics if topic in recorded
              or topic not in (absolute_topic(LINKAGE_MARKERS_TOPIC), ROBOT_DESCRIPTION_TOPIC)}
    for topic in topics:
        assert recorded.get(topic) == PUBLISHED[topic], topic
    for topic, steps in paths:
        schema = recorded[topic]
        definitions = {}
        text = run.schema_text(schema)
        # rosbag2's form: the type's own text, then each nested type behind a '=' line.
        parts = re.split(r'^=+\n', text, flags=re.MULTILINE)
        definitions.update(get_types_from_msg(parts[0], schema))
        for part in parts[1:]:
            name, body = part.split('\n', 1)
            definitions.update(get_types_from_msg(body, name.replace('MSG: ', '').strip()
                                                  .replace('/', '/msg/', 1)))
        fielddefs = {name: (consts, fields) for name, (consts, fields) in definitions.items()}
        assert _resolve(fielddefs, schema, steps) == 'float64'
    # Recorded joint states carry the joints in the order the plot indices assume.
    deserialize = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr
    _, schema, _, _, data = next(run.messages([JOINT_STATES_TOPIC]))
    assert tuple(deserialize(data, schema).name) == JOINT_NAMES


@pytest.mark.parametrize('name', ['shaper.rviz', 'foxglove_layout.json'])
def test_display_configurations_are_installed(name):
    assert os.path.isfile(os.path.join(get_package_share_directory('qrm_ros'), 'config', name))


SHIPPED = os.path.join(REPO_ROOT, 'config', 'foxglove_layout.json')


def test_shipped_layout_is_the_generated_one(tmp_path):
    expected = foxglove_layout_text(kin.Geometry.paper())
    with open(SHIPPED) as handle:
        assert handle.read() == expected, ('config/foxglove_layout.json is stale: regenerate '
                                           'it with qrm_urdf --foxglove-layout '
                                           'config/foxglove_layout.json')
    assert _layout() == json.loads(expected)  # the installed one too
    path = tmp_path / 'layout.json'
    assert qrm_urdf(['-o', str(tmp_path / 'm.urdf'), '--foxglove-layout', str(path)]) == 0
    assert path.read_text() == expected


def test_every_panel_is_titled_for_foxglove_and_lichtblick():
    for key, config in _layout()['configById'].items():
        assert config.get('foxglovePanelTitle'), key
        assert config.get('lichtblickPanelTitle') == config['foxglovePanelTitle'], key


def test_scene_shows_no_frame_labels_or_axes(tmp_path):
    yourdfpy = pytest.importorskip('yourdfpy')
    (scene,) = _panels('3D').values()
    assert scene['scene']['transforms']['showLabel'] is False
    path = str(tmp_path / 'model.urdf')
    write_urdf(path, kin.Geometry.paper())
    links = yourdfpy.URDF.load(path, load_meshes=False).link_map
    assert scene['transforms'] == {f'frame:{link}': {'visible': False} for link in links}


def _urdf_bounds(geometry, tmp_path):
    """x and y extent of the URDF's visuals over poses across the offset range and a turn."""
    yourdfpy = pytest.importorskip('yourdfpy')
    path = str(tmp_path / 'model.urdf')
    write_urdf(path, geometry)
    model = yourdfpy.URDF.load(path, build_scene_graph=True, load_meshes=False,
                               build_collision_scene_graph=False)
    low, high = np.full(2, np.inf), np.full(2, -np.inf)
    r1 = geometry.coupling_radius
    for offset in (-0.9 * r1, 0.0, 0.9 * r1):
        for angle in np.linspace(0.0, 2 * math.pi, 48, endpoint=False):
            state = kin.state(geometry, offset, angle, 1.0)
            model.update_cfg({'input_shaft_joint': float(angle),
                              'flywheel_joint': float(state.flywheel_angle),
                              'lever_joint': float(state.lever_angle),
                              'ram_joint': float(state.ram_position),
                              'coupling_offset_joint': float(offset)})
            bounds = model.scene.bounds
            low, high = np.minimum(low, bounds[0][:2]), np.maximum(high, bounds[1][:2])
    return low, high


GEOMETRIES = [kin.Geometry.paper(),
              kin.Geometry(0.03, 0.07, 0.16, ram_height=0.35, crank_phase=0.4)]


@pytest.mark.parametrize('geometry', GEOMETRIES, ids=['paper', 'phased'])
def test_camera_frames_the_machine_the_urdf_draws(geometry, tmp_path):
    """
    The orthographic view (height = distance, width = distance x the panel's aspect, centred
    on the target offset in shaper_base) holds the URDF at every pose and is filled by it.
    """
    camera = json.loads(foxglove_layout_text(geometry))['configById']['3D!linkage'][
        'cameraState']
    assert camera['perspective'] is False and camera['phi'] == 0
    assert camera['thetaOffset'] == 0 and camera['target'] == [0, 0, 0]
    centre = np.array(camera['targetOffset'][:2])
    half = 0.5 * camera['distance'] * np.array([PANEL_ASPECT, 1.0])
    low, high = _urdf_bounds(geometry, tmp_path)
    assert np.all(centre - half <= low) and np.all(high <= centre + half)
    # It fills the view in one direction but for the margin and the room left for the
    # markers' label above it (and the workpiece below).
    assert max((high - low) / (2 * half)) > 0.7
    # The drawn extent the layout frames holds the URDF (and the markers' label above it).
    bounds = machine_view_bounds(geometry)
    assert bounds.x_min <= low[0] + 1e-9 and high[0] <= bounds.x_max + 1e-9
    assert bounds.y_min <= low[1] + 1e-9 and high[1] <= bounds.y_max + 1e-9
