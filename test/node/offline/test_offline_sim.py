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
One truth: a scenario simulated offline is what the recorder records of the live node.

The same scenario runs twice. Offline, through qrm_ros.node.offline.offline_sim. Live: shaper_sim
on use_sim_time, driven by /clock at the same stamps one tick at a time, its parameters set
through its parameter service, its speed commanded on input_speed_cmd, reset through its
service, and recorded by the real mcap_recorder process. The two files then hold bit-identical
joint states and twists, the same stroke-pair diagnostics key by key, the same parameter
changes, QoS metadata and type hashes, the same parameter metadata, and the same machine
(URDF and link transforms).
"""

import json
import signal
import struct
import subprocess

from builtin_interfaces.msg import Time as TimeMessage
from geometry_msgs.msg import TwistStamped
import pytest
from rcl_interfaces.msg import ParameterEvent
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message
from rosbags.typesys import get_typestore, Stores
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from diagnostic_msgs.msg import DiagnosticArray
from qrm_ros.core.common.names import CUTTING_SPEED_STATUS, PARAMETERS_METADATA, STROKE_PAIR_STATUS
from qrm_ros.node.offline.offline_sim import Simulation, THEORY_TIMEOUT
from qrm_ros.node.offline.scenario import scenario_from_mapping, ScenarioError
from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode
from qrm_ros.recording.bag_reader import open_run
from ros_probe import BackgroundSpinner, call, installed_executable, stamp_ns, stop_process
from ros_probe import wait_for

NS = 1_000_000_000
STORE = get_typestore(Stores.ROS2_JAZZY)
PERIOD_NS = 10_000_000  # 100 Hz, the default publish_rate
SCENARIO = {
    'duration': 6.0,
    'start_time': 1.5,
    'parameters': {'coupling_offset': 0.005, 'input_speed': 9.0, 'offset_rate_limit': 0.02},
    'events': [{'at': 1.5, 'set': {'coupling_offset': 0.012}},
               {'at': 3.0, 'input_speed_cmd': 7.5},
               {'at': 4.5, 'reset': True}],
}


def _offline(path, drive):
    data = dict(SCENARIO, parameters=dict(SCENARIO['parameters'], drive=drive))
    summary = Simulation(scenario_from_mapping(data), str(path)).run()
    assert summary.ticks == 600 and not summary.stopped
    return summary


class _LiveRun:
    """The node on /clock, a probe that drives it, and the recorder recording them."""

    def __init__(self, context, path, drive):
        parameters = dict(SCENARIO['parameters'], drive=drive, use_sim_time=True)
        self.node = ShaperSimNode(context=context, parameter_overrides=[
            Parameter(name, value=value) for name, value in parameters.items()])
        self.node.stroke_pairs.theory_timeout = THEORY_TIMEOUT  # as offline: no 'pending'
        self.probe = Node('scenario_probe', context=context)
        self.clock = self.probe.create_publisher(Clock, '/clock', 10)
        self.speed = self.probe.create_publisher(Float64, 'input_speed_cmd', 10)
        self.stamps = []
        self.probe.create_subscription(JointState, 'joint_states',
                                       lambda m: self.stamps.append(stamp_ns(m)), 1000)
        self.parameters = AsyncParameterClient(self.probe, 'shaper_sim')
        self.reset = self.probe.create_client(Trigger, '/shaper_sim/reset')
        self.spinner = BackgroundSpinner(context, self.node, self.probe)
        self.recorder = subprocess.Popen(
            [installed_executable('mcap_recorder'), '--ros-args', '-p', f'output:={path}'],
            stderr=subprocess.PIPE, text=True)

    def wait_until_recorded(self):
        """Wait until the recorder listens to every topic the scenario produces."""
        node = self.node
        for topic in ('/joint_states', '/ram/twist', '/diagnostics', '/parameter_events'):
            wait_for(lambda: any(info.node_name == 'mcap_recorder'
                                 for info in node.get_subscriptions_info_by_topic(topic)),
                     60.0, f'the recorder on {topic}')
        wait_for(lambda: self.speed.get_subscription_count() >= 2, 60.0,
                 'the node and the recorder on input_speed_cmd')

    def tick(self, stamp):
        self.clock.publish(Clock(clock=_time(stamp)))
        # Long: a report waits in the node's thread for its effort theory (a worker's first
        # theory of a motor setting takes seconds on a loaded machine).
        wait_for(lambda: self.stamps and self.stamps[-1] == stamp, THEORY_TIMEOUT,
                 f'the tick at {stamp}')

    def apply(self, event):
        kind, value = event.kind, event.value
        if kind == 'set':
            future = self.parameters.set_parameters_atomically(
                [Parameter(name, value=v) for name, v in value.items()])
            wait_for(future.done, 20.0, 'the parameter service')
            assert future.result().result.successful
        elif kind == 'input_speed_cmd':
            self.speed.publish(Float64(data=value))
            wait_for(lambda: self.node.speed_command == value, 20.0, 'the speed command')
        else:
            assert kind == 'reset'
            assert call(self.reset, Trigger.Request()).success

    def finish(self):
        self.node.wait_for_pair_reports()
        code = stop_process(self.recorder)
        errors = self.recorder.stderr.read()
        self.spinner.stop()
        self.node.destroy_node()
        self.probe.destroy_node()
        assert code == 0, errors


def _time(stamp):
    return TimeMessage(sec=stamp // NS, nanosec=stamp % NS)


def _live(context, path, drive):
    scenario = scenario_from_mapping(dict(SCENARIO, parameters={}))
    start_ns = round(scenario.start_time * NS)
    live = _LiveRun(context, path, drive)
    try:
        live.wait_until_recorded()
        live.clock.publish(Clock(clock=_time(start_ns)))
        events = list(scenario.events)
        end_ns = start_ns + round(scenario.duration * NS)
        for stamp in range(start_ns + PERIOD_NS, end_ns + 1, PERIOD_NS):
            while events and start_ns + round(events[0].at * NS) <= stamp:
                live.apply(events.pop(0))
            live.tick(stamp)
    finally:
        live.finish()


def _messages(path, topic):
    return [m.data for m in open_run(path).messages(topic)]


def _bits(path, topic):
    """
    Every field of a topic's messages, floats as their bytes.

    Not the serialized bytes themselves: CDR leaves the padding after a string undefined, and
    rclpy's serialize_message leaves there whatever its buffer held.
    """
    if topic == '/joint_states':
        return [(m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id, list(m.name),
                 m.position.tobytes(), m.velocity.tobytes(), m.effort.tobytes())
                for m in (deserialize_message(d, JointState) for d in _messages(path, topic))]
    return [(m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id,
             struct.pack('<6d', m.twist.linear.x, m.twist.linear.y, m.twist.linear.z,
                         m.twist.angular.x, m.twist.angular.y, m.twist.angular.z))
            for m in (deserialize_message(d, TwistStamped) for d in _messages(path, topic))]


def _unstamped(path, topic):
    """A TFMessage topic's transforms (frames and poses), without their stamps."""
    found = []
    for data in _messages(path, topic):
        for transform in STORE.deserialize_cdr(data, 'tf2_msgs/msg/TFMessage').transforms:
            pose = transform.transform
            found.append((transform.header.frame_id, transform.child_frame_id,
                          pose.translation.x, pose.translation.y, pose.translation.z,
                          pose.rotation.x, pose.rotation.y, pose.rotation.z, pose.rotation.w))
    return found


def _statuses(path):
    found = []
    for data in _messages(path, '/diagnostics'):
        for status in deserialize_message(data, DiagnosticArray).status:
            found.append((status.name, status.level, status.message,
                          {kv.key: kv.value for kv in status.values}))
    return found


def _changes(path):
    found = []
    for data in _messages(path, '/parameter_events'):
        event = deserialize_message(data, ParameterEvent)
        if event.node == '/shaper_sim':
            found.append((event.stamp.sec, event.stamp.nanosec,
                          [(p.name, p.value.double_value) for p in event.changed_parameters]))
    return found


@pytest.mark.parametrize('drive', ['speed', pytest.param('motor', marks=pytest.mark.slow)])
def test_offline_run_is_the_live_recording(context, tmp_path, drive):
    offline, live = tmp_path / 'offline.mcap', tmp_path / 'live.mcap'
    _offline(offline, drive)
    _live(context, live, drive)
    for topic in ('/joint_states', '/ram/twist'):
        offline_messages, live_messages = _bits(offline, topic), _bits(live, topic)
        assert len(offline_messages) == 600
        assert offline_messages == live_messages, topic
    # The machine beside them, written by the recorder's own code in both; the fixed
    # transforms are stamped when the recorder learns the geometry (live: its wall clock).
    for topic in ('/tf', '/robot_description'):
        assert _messages(offline, topic) == _messages(live, topic), topic
    assert len(_messages(offline, '/tf')) == 600
    assert _unstamped(offline, '/tf_static') == _unstamped(live, '/tf_static') != []
    offline_statuses, live_statuses = _statuses(offline), _statuses(live)
    pairs = [s for s in offline_statuses if s[0] == STROKE_PAIR_STATUS]
    assert len(pairs) >= 4 and any(s[3].get('effort_theory') == 'steady setting' for s in pairs)
    assert len(offline_statuses) == len(live_statuses)
    for offline_status, live_status in zip(offline_statuses, live_statuses):
        assert offline_status[:3] == live_status[:3]
        assert offline_status[3].keys() == live_status[3].keys()
        for key, value in offline_status[3].items():
            assert value == live_status[3][key], key
    assert _changes(offline) == _changes(live) != []
    offline_run, live_run = open_run(offline), open_run(live)
    for topic in ('/joint_states', '/ram/twist', '/diagnostics'):
        assert offline_run.channel_metadata(topic) == live_run.channel_metadata(topic)
    assert offline_run.topics().items() <= live_run.topics().items()
    assert (json.loads(offline_run.metadata[PARAMETERS_METADATA]['drive'])
            == json.loads(live_run.metadata[PARAMETERS_METADATA]['drive']) == drive)
    assert offline_run.metadata[PARAMETERS_METADATA] == live_run.metadata[PARAMETERS_METADATA]


def test_refused_event_leaves_no_file(tmp_path):
    path = tmp_path / 'refused.mcap'
    scenario = scenario_from_mapping({'duration': 1.0, 'events': [
        {'at': 0.5, 'set': {'coupling_offset': 0.05}}]})
    with pytest.raises(ScenarioError, match=r'event at 0\.5 s refused by the node: '
                       r'coupling_offset = 0\.05 refused: outside the allowed range'):
        Simulation(scenario, str(path)).run()
    assert not path.exists()


def test_refused_start_up_value_leaves_no_file(tmp_path):
    path = tmp_path / 'refused.mcap'
    with pytest.raises(ValueError, match='input_speed = 100.0 refused'):
        Simulation(scenario_from_mapping({'duration': 1.0, 'parameters': {
            'input_speed': 100.0}}), str(path))
    assert not path.exists()


def test_pause_holds_the_state_and_publishes_nothing(tmp_path):
    path = tmp_path / 'paused.mcap'
    Simulation(scenario_from_mapping({'duration': 2.0, 'events': [
        {'at': 0.5, 'pause': True}, {'at': 1.5, 'resume': True}]}), str(path)).run()
    states = [deserialize_message(d, JointState) for d in _messages(path, '/joint_states')]
    stamps = [stamp_ns(s) for s in states]
    assert stamps == ([k * PERIOD_NS for k in range(1, 50)]
                      + [k * PERIOD_NS for k in range(150, 201)])
    # No motion during the pause: the first sample after it is the held state, and the
    # shaft goes on from there at its speed (2 pi rad/s, 10 ms a tick).
    before, after, next_one = states[48], states[49], states[50]
    assert after.position.tobytes() == before.position.tobytes()
    assert next_one.position[0] - after.position[0] == pytest.approx(
        2 * 3.141592653589793 * 0.01, rel=1e-9)


def test_stop_request_finishes_the_file(tmp_path):
    path = tmp_path / 'stopped.mcap'

    class StopAfter:
        calls = 0

        def __bool__(self):
            self.calls += 1
            return self.calls >= 25
    summary = Simulation(scenario_from_mapping({'duration': 100.0}), str(path)).run(
        stop=StopAfter())
    assert summary.stopped and summary.ticks == 25
    assert len(_messages(path, '/joint_states')) == 25
    # Every joint state's transforms too (they are written a batch at a time), at its time.
    run = open_run(path)
    assert ([m.log_time for m in run.messages('/tf')]
            == [m.log_time for m in run.messages('/joint_states')])


def test_signal_stops_the_command_cleanly(tmp_path):
    path = tmp_path / 'interrupted.mcap'
    process = subprocess.Popen(
        [installed_executable('qrm_simulate'), '--duration', '100000', '-o', str(path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: path.exists() and path.stat().st_size > 100_000, 60.0, 'the run under way')
    code = stop_process(process, signal.SIGTERM, 30.0)
    assert code == 128 + signal.SIGTERM, process.stderr.read()
    assert 'Traceback' not in process.stderr.read()
    assert len(_messages(path, '/joint_states')) > 100


def test_a_held_cutting_speed_is_held_offline(tmp_path):
    path = tmp_path / 'hold.mcap'
    # Set by an event: the node refuses a cutting speed target at start-up (its
    # coupling_offset check sees the target).
    Simulation(scenario_from_mapping({'duration': 12.0, 'parameters': {
        'offset_rate_limit': 0.02, 'input_speed': 9.0}, 'events': [
            {'at': 0.0, 'set': {'cutting_speed_target': 0.4}}]}), str(path)).run()
    statuses = _statuses(path)
    holds = [s for s in statuses if s[0] == CUTTING_SPEED_STATUS]
    assert holds and holds[0][1] == b'\x00'  # OK: reachable
    steady = [s[3] for s in statuses if s[0] == STROKE_PAIR_STATUS
              and s[3]['offset_steady'] == 'true']
    assert len(steady) >= 3
    for values in steady:
        assert float(values['cutting_speed_measured']) == pytest.approx(0.4, rel=1e-3)
        assert float(values['cutting_speed_error']) == pytest.approx(0.0, abs=1e-3)
