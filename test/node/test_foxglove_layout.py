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
publishes, and in a recording made by the real node and recorder (the golden logs).
"""

import json
import os
import re

from ament_index_python.packages import get_package_share_directory
import pytest
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
from rosbags.typesys.base import Nodetype

from qrm_ros.recording.bag_reader import open_run
from qrm_ros.core.names import (absolute_topic, DIAGNOSTICS_TOPIC, JOINT_NAMES, JOINT_STATE_TYPE,
                                JOINT_STATES_TOPIC, LINKAGE_MARKERS_TOPIC, LINKAGE_MARKERS_TYPE,
                                RAM_TWIST_TOPIC, SIM_NODE_NAME, STROKE_PAIR_STATUS)
from qrm_ros.recording.urdf_model import BASE_LINK
from repo_paths import TEST_DATA

GOLDEN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')
# What the node publishes, by recorded topic name.
PUBLISHED = {
    absolute_topic(JOINT_STATES_TOPIC): JOINT_STATE_TYPE,
    absolute_topic(RAM_TWIST_TOPIC): 'geometry_msgs/msg/TwistStamped',
    absolute_topic(DIAGNOSTICS_TOPIC): 'diagnostic_msgs/msg/DiagnosticArray',
    absolute_topic(LINKAGE_MARKERS_TOPIC): LINKAGE_MARKERS_TYPE,
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
    assert list(scene['topics']) == [absolute_topic(LINKAGE_MARKERS_TOPIC)]
    (status,) = _panels('DiagnosticStatusPanel').values()
    assert status['selectedHardwareId'] == SIM_NODE_NAME
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
    markers = absolute_topic(LINKAGE_MARKERS_TOPIC)
    if markers not in recorded:
        topics = topics - {markers}  # the golden logs predate the node's markers
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
