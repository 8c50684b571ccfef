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
qrm_bridge over real DDS, seen by Foxglove's own protocol client (npm, run with Node.js).

shaper_sim and qrm_bridge run as their own processes; the client decodes the CDR with
Foxglove's ROS 2 reader from the schema the bridge advertised, and the values are compared
with what a DDS subscriber in this process received: the same messages, bit for bit. Then the
client steers the node as the app's panels do (parameters, services, publishing) and the node's
answer is checked over DDS.
"""

import os
import subprocess

from ament_index_python.packages import get_package_share_directory
import pytest
from qrm_ros.core.common.names import PUBLISHED_JOINT_NAMES
from qrm_ros.node.bridge.foxglove_bridge import package_asset
from qrm_ros.recording.rosbag2_formats import DEFINITION_DELIMITER, find_message_definition
from rcl_interfaces.srv import GetParameters, SetParameters
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter, parameter_value_to_python
from sensor_msgs.msg import JointState
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from foxglove_client import bridge_address, FoxgloveClient, node_executable, node_modules
from ros_probe import BackgroundSpinner, call, installed_executable, stop_process, wait_for

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason='Node.js is not installed (Foxglove\'s client runs on it)')

OFFSET = '/shaper_sim.coupling_offset'
FLOAT64 = 'float64 data\n'


def _start(name, *arguments):
    executable = installed_executable(name)
    assert executable, f'the {name} console script is not installed'
    return subprocess.Popen([executable, *arguments], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


class Probe:
    """A DDS subscriber and parameter client in this process."""

    def __init__(self):
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node('bridge_probe', context=self.context)
        self.joint_states = []
        self.subscription = self.node.create_subscription(
            JointState, 'joint_states', self.joint_states.append, 1000)
        self.get_client = self.node.create_client(GetParameters, '/shaper_sim/get_parameters')
        self.set_client = self.node.create_client(SetParameters, '/shaper_sim/set_parameters')
        self.spinner = BackgroundSpinner(self.context, self.node)

    def parameter(self, name):
        answer = call(self.get_client, GetParameters.Request(names=[name]), timeout=15.0)
        return parameter_value_to_python(answer.values[0])

    def set_parameter(self, name, value):
        request = SetParameters.Request(parameters=[RosParameter(name, value=value)
                                                    .to_parameter_msg()])
        return call(self.set_client, request, timeout=15.0).results[0]

    def close(self):
        self.spinner.stop()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


@pytest.fixture(scope='module')
def modules():
    return node_modules()


@pytest.fixture(scope='module')
def running(modules):
    """shaper_sim, qrm_bridge on a free loopback port, and the DDS probe."""
    sim = _start('shaper_sim')
    bridge = _start('qrm_bridge', '--port', '0')
    probe = Probe()
    output = []
    try:
        address = bridge_address(bridge, output)
        wait_for(lambda: probe.subscription.get_publisher_count() > 0, 20.0,
                 "shaper_sim's joint states")
        yield address, probe
    finally:
        probe.close()
        assert stop_process(bridge) == 0
        stop_process(sim)


@pytest.fixture
def client(running, modules):
    made = []

    def connect():
        made.append(FoxgloveClient(running[0], modules))
        made[-1].wait_event('serverInfo')
        return made[-1]
    yield connect
    for item in made:
        item.close()


def _stamp(header):
    return header['stamp']['sec'] * 1_000_000_000 + header['stamp']['nanosec']


def test_joint_states_reach_the_client_as_dds_delivers_them(running, client):
    address, probe = running
    viewer = client()
    assert address.startswith('ws://127.0.0.1:')  # loopback by default
    info = viewer.wait_event('serverInfo')
    assert {'parameters', 'services', 'clientPublish', 'assets'} <= set(info['capabilities'])
    viewer.send(op='subscribe', topic='/joint_states')
    advertised = viewer.wait_event('advertise', topic='/joint_states')
    assert (advertised['encoding'], advertised['schemaEncoding'], advertised['schemaName']) == (
        'cdr', 'ros2msg', 'sensor_msgs/msg/JointState')
    assert advertised['schema'] == find_message_definition('sensor_msgs/msg/JointState')[0]
    viewer.wait(lambda events: len([e for e in events if e.get('topic') == '/joint_states'
                                    and e['event'] == 'message']) >= 50, what='50 joint states')
    by_stamp = {}

    def probe_caught_up():
        """The DDS probe spins in its own thread and may lag the client on a loaded machine."""
        for message in list(probe.joint_states):
            by_stamp[message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec] = (
                message)
        client_stamps = [_stamp(event['message']['header'])
                         for event in viewer.matching('message', topic='/joint_states')]
        return sum(stamp in by_stamp for stamp in client_stamps) >= 40

    wait_for(probe_caught_up, 20.0, 'the DDS probe to hold 40 of the stamps the client got')
    matched = 0
    for event in viewer.matching('message', topic='/joint_states'):
        seen = event['message']
        dds = by_stamp.get(_stamp(seen['header']))
        if dds is None:
            continue
        matched += 1
        assert seen['name'] == list(dds.name)
        assert seen['header']['frame_id'] == dds.header.frame_id
        for field in ('position', 'velocity', 'effort'):
            assert seen[field] == list(getattr(dds, field)), field  # the same doubles
    assert matched >= 40


def test_markers_diagnostics_and_services_are_advertised(running, client):
    viewer = client()
    for topic, schema in (('/linkage_markers', 'visualization_msgs/msg/MarkerArray'),
                          ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray')):
        assert viewer.wait_event('advertise', topic=topic)['schemaName'] == schema
    for name, kind in (('/shaper_sim/pause', 'std_srvs/srv/SetBool'),
                       ('/shaper_sim/reset', 'std_srvs/srv/Trigger')):
        assert viewer.wait_event('advertiseService', name=name)['type'] == kind
    viewer.send(op='subscribe', topic='/linkage_markers')
    marker_array = viewer.wait_event('message', topic='/linkage_markers')['message']
    assert marker_array['markers'] and all(
        m['header']['frame_id'] == 'shaper_base' for m in marker_array['markers'])


def test_a_parameter_set_from_the_client_is_the_nodes_to_refuse(running, client):
    _, probe = running
    viewer = client()
    viewer.send(op='getParameters', names=[OFFSET], id='get')
    before = viewer.wait_event('parameterValues', id='get')['parameters']
    assert before == [{'name': OFFSET, 'type': 'float64', 'value': probe.parameter(
        'coupling_offset')}]
    viewer.send(op='setParameters', parameters=[{'name': OFFSET, 'value': 1.0}], id='bad')
    kept = viewer.wait_event('parameterValues', id='bad')['parameters']
    assert kept[0]['value'] == before[0]['value']
    refusal = viewer.wait(lambda events: [e for e in events if e['event'] == 'status'
                                          and OFFSET in e['message']], what='the refusal')
    assert 'outside the allowed range [-0.0225, 0.0225] m' in refusal[0]['message']
    viewer.send(op='setParameters', parameters=[{'name': OFFSET, 'value': 0.01}], id='good')
    assert viewer.wait_event('parameterValues', id='good')['parameters'][0]['value'] == 0.01
    assert probe.parameter('coupling_offset') == 0.01
    viewer.send(op='setParameters', parameters=[{'name': OFFSET, 'value': 0}], id='zero')
    assert viewer.wait_event('parameterValues', id='zero')['parameters'][0]['value'] == 0.0
    viewer.send(op='getParameters', names=[], id='all')
    every = {p['name'] for p in viewer.wait_event('parameterValues', id='all')['parameters']}
    assert {OFFSET, '/shaper_sim.input_speed', '/shaper_sim.publish_rate'} <= every


def test_an_unknown_parameter_of_a_known_node_spoils_not_the_others(running, client):
    """rclpy answers nothing when one name is unknown: the known ones are answered anyway."""
    viewer = client()
    unknown = '/shaper_sim.no_such_parameter'
    viewer.send(op='getParameters', names=[OFFSET, unknown], id='mixed')
    answered = viewer.wait_event('parameterValues', id='mixed')['parameters']
    assert [p['name'] for p in answered] == [OFFSET]
    said = viewer.wait(lambda events: [e for e in events if e['event'] == 'status'
                                       and 'no_such_parameter' in e['message']],
                       what='the unknown parameter said')
    assert 'no parameter no_such_parameter on node /shaper_sim' in said[0]['message']


def test_pause_and_reset_are_called_from_the_client(running, client):
    _, probe = running
    viewer = client()
    viewer.wait_event('advertiseService', name='/shaper_sim/pause')
    viewer.send(op='call', service='/shaper_sim/pause', request={'data': True})
    answer = viewer.wait_event('serviceCallResponse', service='/shaper_sim/pause')['response']
    assert answer == {'success': True, 'message': 'paused'}
    viewer.send(op='call', service='/shaper_sim/reset', request={})
    reset = viewer.wait_event('serviceCallResponse', service='/shaper_sim/reset')['response']
    assert reset['success'] and reset['message'].startswith('reset: input angle 0 rad')
    viewer.events.clear()
    viewer.send(op='call', service='/shaper_sim/pause', request={'data': False})
    answer = viewer.wait_event('serviceCallResponse', service='/shaper_sim/pause')['response']
    assert answer == {'success': True, 'message': 'running'}


def test_the_node_follows_a_speed_command_published_by_the_client(running, client):
    _, probe = running
    viewer = client()
    other = client()
    viewer.send(op='advertise', topic='input_speed_cmd', schemaName='std_msgs/msg/Float64',
                schema=FLOAT64)
    viewer.send(op='publishBytes', topic='input_speed_cmd', hex='01')  # not a Float64
    error = viewer.wait(lambda events: [e for e in events if e['event'] == 'status'
                                        and 'not a CDR Float64' in e['message']],
                        what='the malformed message refused')
    assert error[0]['level'] == 2  # error
    viewer.send(op='publish', topic='input_speed_cmd', message={'data': 3.0})
    wait_for(lambda: probe.joint_states and probe.joint_states[-1].velocity[0] == 3.0, 20.0,
             'the input speed to reach the commanded 3.0 rad/s')
    assert other.wait_event('serverInfo')  # the other client is still served
    other.send(op='subscribe', topic='/joint_states')
    other.wait_event('message', topic='/joint_states')


def test_what_dds_refuses_from_a_client_is_said_to_it(running, client):
    """A Float64 with a trailing byte reads as one but DDS refuses it; a bad topic name."""
    viewer = client()
    viewer.send(op='advertise', topic='input_speed_cmd', schemaName='std_msgs/msg/Float64',
                schema=FLOAT64)
    # A CDR header and 3.0, then one byte too many.
    viewer.send(op='publishBytes', topic='input_speed_cmd', hex='00010000' '0000000000000840'
                '00')
    refused = viewer.wait(lambda events: [e for e in events if e['event'] == 'status'
                                          and 'DDS refused' in e['message']],
                          what='the refusal said to the client')
    assert refused[0]['level'] == 2 and '13-byte Float64' in refused[0]['message']
    viewer.send(op='advertise', topic='bad topic!!', schemaName='std_msgs/msg/Float64',
                schema=FLOAT64)
    bad = viewer.wait(lambda events: [e for e in events if e['event'] == 'status'
                                      and 'not a valid ROS topic name' in e['message']],
                      what='the bad topic name said to the client')
    assert "client channel 'bad topic!!'" in bad[0]['message'] and bad[0]['level'] == 2


def test_a_malformed_protocol_message_gets_an_error_for_that_client_only(running, client):
    sender, bystander = client(), client()
    sender.send(op='raw', text='{"op": "subscribe", "subscriptions": "not a list"')
    status = sender.wait_event('status', level=2)
    assert 'Invalid message' in status['message']
    bystander.send(op='subscribe', topic='/joint_states')
    bystander.wait_event('message', topic='/joint_states')
    sender.send(op='subscribe', topic='/joint_states')  # the sender is still served too
    sender.wait_event('message', topic='/joint_states')
    assert not bystander.matching('status', level=2)


def test_topics_are_advertised_when_they_appear_and_removed_when_they_vanish(running, client):
    _, probe = running
    viewer = client()
    publisher = probe.node.create_publisher(String, 'bridge_test_topic', 10)
    advertised = viewer.wait_event('advertise', topic='/bridge_test_topic')
    assert advertised['schemaName'] == 'std_msgs/msg/String'
    viewer.send(op='subscribe', topic='/bridge_test_topic')
    viewer.wait_event('subscribed', topic='/bridge_test_topic')

    def published():
        publisher.publish(String(data='seen'))
        return viewer.matching('message', topic='/bridge_test_topic')
    wait_for(published, 20.0, 'the new topic forwarded')
    assert published()[0]['message'] == {'data': 'seen'}
    probe.node.destroy_publisher(publisher)
    viewer.wait_event('unadvertise', topic='/bridge_test_topic')


def test_the_urdf_is_served_as_an_asset_and_nothing_outside_the_share_folder(running, client):
    viewer = client()
    uri = 'package://qrm_ros/urdf/qrm_shaper.urdf'
    viewer.send(op='fetchAsset', uri=uri)
    answer = viewer.wait_event('fetchAssetResponse')
    path = os.path.join(get_package_share_directory('qrm_ros'), 'urdf', 'qrm_shaper.urdf')
    with open(path) as handle:
        assert (answer['status'], answer['text']) == (0, handle.read())
    assert package_asset(uri) == open(path, 'rb').read()
    assert package_asset('package://qrm_ros/../../../../etc/hostname') is None
    assert package_asset('file:///etc/hostname') is None
    assert package_asset('package://no_such_package/x') is None


@pytest.mark.parametrize('arguments, words', [
    (['--port', '70000'], '--port 70000 is outside 0-65535'),
    (['--client-queue', '0'], '--client-queue 0 is outside 1-1000000'),
    (['--send-period', '2'], '--send-period 2 s is outside 0-1 s'),
    (['--send-period', 'nan'], '--send-period nan s is outside 0-1 s'),
])
def test_bad_options_exit_2_with_one_line(arguments, words):
    result = subprocess.run([installed_executable('qrm_bridge'), *arguments],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert words in result.stderr and 'Traceback' not in result.stderr


def test_a_taken_port_exits_1_with_one_line(running):
    port = running[0].rsplit(':', 1)[1]
    result = subprocess.run([installed_executable('qrm_bridge'), '--port', port],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1, result.stderr
    assert f'cannot serve on 127.0.0.1 port {port}' in result.stderr
    assert 'Traceback' not in result.stderr


def test_a_topic_is_subscribed_on_ros_only_while_a_client_wants_it(running, client):
    _, probe = running

    def bridge_subscribed():
        return [info for info in probe.node.get_subscriptions_info_by_topic('/joint_states')
                if info.node_name == 'qrm_bridge']
    wait_for(lambda: not bridge_subscribed(), 20.0, 'no client, no ROS subscription')
    first, second = client(), client()
    for viewer in (first, second):
        viewer.send(op='subscribe', topic='/joint_states')
        viewer.wait_event('message', topic='/joint_states')
    assert len(bridge_subscribed()) == 1  # one ROS subscription, whatever the clients
    first.close()  # a client leaving mid-stream: the other is still served
    count = len(second.matching('message', topic='/joint_states'))
    second.wait(lambda events: len([e for e in events if e.get('topic') == '/joint_states'
                                    and e['event'] == 'message']) > count + 10,
                what='more joint states after the other client left')
    second.close()
    wait_for(lambda: not bridge_subscribed(), 20.0, 'the ROS subscription dropped')


def test_a_latched_topic_reaches_a_client_that_subscribes_later(running, client):
    _, probe = running
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)  # as robot_state_publisher's
    publisher = probe.node.create_publisher(String, '/bridge_test_latched', latched)
    publisher.publish(String(data='<robot name="qrm_shaper"/>'))
    try:
        viewer = client()
        viewer.wait_event('advertise', topic='/bridge_test_latched')
        viewer.send(op='subscribe', topic='/bridge_test_latched')
        got = viewer.wait_event('message', topic='/bridge_test_latched')
        assert got['message'] == {'data': '<robot name="qrm_shaper"/>'}
    finally:
        probe.node.destroy_publisher(publisher)


def test_the_machine_is_served_for_the_3d_panel_without_robot_state_publisher(running, client):
    _, probe = running
    viewer = client()
    for topic in ('/robot_description', '/tf_static', '/tf'):
        viewer.send(op='subscribe', topic=topic)
    description = viewer.wait_event('message', topic='/robot_description', timeout=30.0)
    path = os.path.join(get_package_share_directory('qrm_ros'), 'urdf', 'qrm_shaper.urdf')
    with open(path) as handle:  # the simulator runs the default geometry, the installed URDF's
        assert description['message']['data'] == handle.read()
    fixed = viewer.wait_event('message', topic='/tf_static')['message']['transforms']
    moving = viewer.wait_event('message', topic='/tf')['message']['transforms']
    assert {t['child_frame_id'] for t in fixed}.isdisjoint(t['child_frame_id'] for t in moving)
    assert len(moving) == len(PUBLISHED_JOINT_NAMES)  # one per moving joint
    # Nested types are defined as in every other channel (a viewer compares them).
    tf_schema = viewer.wait_event('advertise', topic='/tf')['schema']
    markers_schema = viewer.wait_event('advertise', topic='/linkage_markers')['schema']
    quaternion = 'MSG: geometry_msgs/Quaternion\n'
    assert (tf_schema.split(quaternion)[1].split(DEFINITION_DELIMITER)[0]
            == markers_schema.split(quaternion)[1].split(DEFINITION_DELIMITER)[0])
    # Stamped as the joint state they are computed from, which DDS delivered here too.
    wait_for(lambda: _stamp(moving[0]['header']) in {
        m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        for m in list(probe.joint_states)}, 10.0, 'the joint state the transforms are of')


def test_a_change_made_over_ros_reaches_a_client_subscribed_to_the_parameter(running, client):
    _, probe = running
    viewer = client()
    viewer.send(op='subscribeParameterUpdates', names=[OFFSET])
    viewer.send(op='getParameters', names=[OFFSET], id='subscribed')  # the subscription is in
    viewer.wait_event('parameterValues', id='subscribed')
    try:
        assert probe.set_parameter('coupling_offset', -0.005).successful
        update = viewer.wait(lambda events: [e for e in events if e['event'] == 'parameterValues'
                                             and e.get('id') is None
                                             and e['parameters'][0]['value'] == -0.005],
                             what='the update from /parameter_events')
        assert update[0]['parameters'] == [{'name': OFFSET, 'type': 'float64', 'value': -0.005}]
    finally:
        probe.set_parameter('coupling_offset', 0.0)


def test_topics_limits_what_is_served(running, modules):
    bridge = _start('qrm_bridge', '--port', '0', '--topics', 'joint_states')
    viewer = None
    try:
        viewer = FoxgloveClient(bridge_address(bridge, []), modules)
        viewer.send(op='subscribe', topic='/joint_states')
        viewer.wait_event('message', topic='/joint_states')
        assert {e['topic'] for e in viewer.matching('advertise')} == {'/joint_states'}
    finally:
        if viewer is not None:
            viewer.close()
        assert stop_process(bridge) == 0


def test_an_address_not_of_this_machine_exits_1_with_one_line():
    # 192.0.2.1 is a documentation address (RFC 5737): binding to it fails here, nothing is sent.
    result = subprocess.run([installed_executable('qrm_bridge'), '--address', '192.0.2.1',
                             '--port', '0'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    assert 'cannot serve on 192.0.2.1 port 0' in result.stderr
    assert 'Traceback' not in result.stderr
