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
mcap_player over real DDS: every message arrives as recorded, in order; the services; /clock.

The player runs as its command; a probe node in the test subscribes to the raw bytes and
compares them with the file read by bag_reader. Its timing is measured by
bench/bench_player.py, not here.
"""

import os
import signal
import subprocess

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                QosReliability, QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger

from qrm_ros.cli import exit_codes
from qrm_ros.node.player.mcap_player import CLOCK_QOS, played_qos
from qrm_ros.recording.bag_reader import open_run
from repo_paths import TEST_DATA
from ros_probe import BackgroundSpinner, call, installed_executable, stop_process, wait_for
from synthetic_run import write_truncated_run

GOLDEN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')
RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


class _Probe:
    """Raw subscribers on the played topics, spun in the background."""

    def __init__(self, context, topics):
        self.node = Node('player_probe', context=context)
        self.received = {topic: [] for topic in topics}
        self.order = []
        for topic, kind in topics.items():
            self.node.create_subscription(kind, topic, self._keeper(topic), RELIABLE,
                                          raw=True)
        self.spinner = BackgroundSpinner(context, self.node)

    def _keeper(self, topic):
        def keep(data):
            self.received[topic].append(data)
            self.order.append(topic)
        return keep

    def matched(self, topic):
        return self.node.count_publishers(topic) > 0

    def close(self):
        self.spinner.stop()
        self.node.destroy_node()


def _player(*args):
    return subprocess.Popen([installed_executable('mcap_player'), *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _play_to_end(context, path, topics, *args):
    """Play a file (started paused until the probe is matched); return probe, code, stderr."""
    probe = _Probe(context, topics)
    player = _player(path, '--start-paused', *args)
    try:
        for topic in topics:
            wait_for(lambda: probe.matched(topic), 20.0, f'the player on {topic}')
        client = probe.node.create_client(Trigger, '/mcap_player/resume')
        assert call(client, Trigger.Request(), 20.0).success
        code = player.wait(120)
        errors = player.stderr.read()
        assert 'Traceback' not in errors
    finally:
        if player.poll() is None:
            stop_process(player)
    return probe, code, errors


def _recorded(path, topics):
    return [(m.topic, m.data) for m in open_run(path).messages(list(topics))]


def test_every_message_arrives_as_recorded_and_in_order(context):
    topics = {'/joint_states': JointState, '/diagnostics': DiagnosticArray}
    probe, code, errors = _play_to_end(context, GOLDEN, topics, '--rate', '5')
    try:
        recorded = _recorded(GOLDEN, topics)
        wait_for(lambda: len(probe.order) == len(recorded), 20.0, 'every message')
        assert code == exit_codes.EXIT_OK, errors
        # In order on each topic (across topics, DDS and the executor keep no order).
        for topic in topics:
            assert probe.received[topic] == [data for t, data in recorded if t == topic]
    finally:
        probe.close()


def test_pause_step_and_resume(context):
    probe = _Probe(context, {'/joint_states': JointState})
    player = _player(GOLDEN, '--start-paused', '--topics', 'joint_states')
    recorded = [data for _, data in _recorded(GOLDEN, ['/joint_states'])]
    try:
        wait_for(lambda: probe.matched('/joint_states'), 20.0, 'the player')
        step = probe.node.create_client(Trigger, '/mcap_player/play_next')
        for count in (1, 2, 3):
            assert call(step, Trigger.Request(), 20.0).success
            wait_for(lambda: len(probe.order) == count, 20.0, f'message {count}')
        assert probe.received['/joint_states'] == recorded[:3]
        toggle = probe.node.create_client(Trigger, '/mcap_player/toggle_paused')
        assert call(toggle, Trigger.Request(), 20.0).message == 'playing'
        assert not call(step, Trigger.Request(), 20.0).success  # not paused
        wait_for(lambda: len(probe.order) > 10, 20.0, 'the playback under way')
        pause = probe.node.create_client(Trigger, '/mcap_player/pause')
        assert call(pause, Trigger.Request(), 20.0).success
        # Paused: what was under way arrives, then one message per step.
        assert call(step, Trigger.Request(), 20.0).success
        wait_for(lambda: probe.received['/joint_states'] == recorded[:len(probe.order)],
                 20.0, 'the messages in order')
        held = len(probe.order)
        assert held < len(recorded)
        resume = probe.node.create_client(Trigger, '/mcap_player/resume')
        assert call(resume, Trigger.Request(), 20.0).success
        assert player.wait(60) == exit_codes.EXIT_OK
        wait_for(lambda: len(probe.order) == len(recorded), 20.0, 'every message')
        assert probe.received['/joint_states'] == recorded
        # Its own timing, said at the end: every message's lateness against its due time.
        assert (f'played {len(recorded)} messages on 1 topics; sent after their recorded '
                'time by ') in player.stdout.read()
    finally:
        stop_process(player)
        probe.close()


def test_clock_follows_the_recorded_time(context):
    probe = _Probe(context, {'/joint_states': JointState})
    clock = []
    probe.node.create_subscription(Clock, '/clock', clock.append, CLOCK_QOS)
    player = _player(GOLDEN, '--clock', '200', '--rate', '4', '--start-offset', '1.0',
                     '--delay', '0.5', '--start-paused')
    try:
        wait_for(lambda: probe.matched('/clock'), 20.0, 'the player on /clock')
        resume = probe.node.create_client(Trigger, '/mcap_player/resume')
        assert call(resume, Trigger.Request(), 20.0).success
        assert player.wait(60) == exit_codes.EXIT_OK
        wait_for(lambda: len(probe.order) == len(times) - skipped, 20.0, 'every message')
    finally:
        stop_process(player)
        probe.close()
    stamps = [c.clock.sec * 1_000_000_000 + c.clock.nanosec for c in clock]
    assert len(stamps) > 50
    assert stamps == sorted(stamps)
    # From the start offset (a clock period before the first message played) to the end.
    assert times[0] + 1_000_000_000 - 5_000_000 * 4 <= stamps[0]
    # Up to the last message played, of any topic: the run ends with a /ram/twist written
    # 84 us after the last joint state, and /clock may reach it.
    assert stamps[-1] <= last_played


times = [m.log_time for m in open_run(GOLDEN).messages('/joint_states')]
skipped = sum(1 for t in times if t - times[0] < 1_000_000_000)
last_played = max(m.log_time for m in open_run(GOLDEN).messages())


def _rosbag2_file(folder):
    """Write a rosbag2 MCAP bag with the rosbags library (rosbag2's own layout)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    bag = folder / 'bag'
    infinite = QosTime(sec=2147483647, nsec=4294967295)
    qos = Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
              infinite, infinite, QosLiveliness.AUTOMATIC, infinite, False)
    message_type = store.types['std_msgs/msg/String']
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection('/chatter', 'std_msgs/msg/String', typestore=store,
                                           offered_qos_profiles=[qos])
        for index in range(20):
            data = store.serialize_cdr(message_type(data=f'hello {index}'),
                                       'std_msgs/msg/String')
            writer.write(connection, 1_000_000_000 + index * 10_000_000, bytes(data))
    return next(bag.glob('*.mcap'))


def test_a_rosbag2_recording_plays_with_its_qos(context, tmp_path):
    path = _rosbag2_file(tmp_path)
    qos = played_qos(open_run(path).channel_metadata('/chatter')['offered_qos_profiles'])
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL and qos.depth == 10
    assert qos.reliability == ReliabilityPolicy.RELIABLE
    probe, code, errors = _play_to_end(context, path, {'/chatter': String})
    try:
        recorded = _recorded(path, ['/chatter'])
        wait_for(lambda: len(probe.order) == 20, 20.0, 'every message')
        assert code == exit_codes.EXIT_OK, errors
        # The bytes as recorded; DDS pads a payload to a multiple of 4 bytes with zeros.
        for received, (_, data) in zip(probe.received['/chatter'], recorded):
            assert received == data + bytes(-len(data) % 4)
    finally:
        probe.close()


def test_a_damaged_file_plays_what_is_readable_and_says_what_was_not(tmp_path):
    cut = write_truncated_run(tmp_path)
    result = subprocess.run([installed_executable('mcap_player'), str(cut), '--rate', '50'],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == exit_codes.EXIT_INCOMPLETE, result.stderr
    assert 'damaged or truncated' in result.stderr and 'Traceback' not in result.stderr
    played = int(result.stdout.split()[1])
    assert 0 < played == sum(1 for _ in open_run(cut).messages())


def test_a_message_dds_refuses_is_skipped_and_said(tmp_path):
    """A Float64 with a trailing byte: DDS refuses to publish it; the rest plays (exit 3)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    kind = store.types['std_msgs/msg/Float64']
    bag = tmp_path / 'bag'
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection('/value', 'std_msgs/msg/Float64', typestore=store)
        for index in range(20):
            data = bytes(store.serialize_cdr(kind(data=float(index)), 'std_msgs/msg/Float64'))
            writer.write(connection, 1_000_000_000 + index * 10_000_000,
                         data + (b'\0' if index in (5, 9) else b''))
    result = subprocess.run([installed_executable('mcap_player'), str(next(bag.glob('*.mcap')))],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == exit_codes.EXIT_INCOMPLETE, result.stderr
    assert 'Traceback' not in result.stderr
    assert result.stdout.startswith('played 18 messages on 1 topics')
    assert 'mcap_player: warning: 2 messages on /value not played: DDS refused them' in (
        result.stderr)


@pytest.mark.parametrize('args, message', [
    (['missing.mcap'], 'does not exist'),
    ([GOLDEN, '--topics', '/nothing'], 'topics /nothing are not in'),
    ([GOLDEN, '--rate', '0'], 'argument --rate'),
    ([GOLDEN, '--delay', '-1'], 'argument --delay'),
    # Finite extremes: a time or a rate whose nanoseconds overflow was an OverflowError.
    ([GOLDEN, '--delay', '1e300'],
     'argument --delay: 1e300 s is not a number in [0, 2147483647] s'),
    ([GOLDEN, '--start-offset', '1e300'], 'argument --start-offset: 1e300 s is not'),
    ([GOLDEN, '--rate', '1e-300'], 'argument --rate: 1e-300 is not a number in [1e-06, 1000000]'),
    ([GOLDEN, '--rate', '1e300'], 'argument --rate: 1e300 is not'),
    ([GOLDEN, '--clock', '1e-300'],
     'argument --clock: 1e-300 Hz is not a number in [0.01, 10000] Hz'),
    ([GOLDEN, '--clock', '1e300'], 'argument --clock: 1e300 Hz is not'),
    ([GOLDEN, '--rate', 'nan'], 'argument --rate: nan is not'),
])
def test_bad_input_is_refused_in_one_line(tmp_path, args, message):
    result = subprocess.run([installed_executable('mcap_player'), *map(str, args)],
                            capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == exit_codes.EXIT_BAD_INPUT
    assert message in result.stderr and 'Traceback' not in result.stderr


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_ends_it_cleanly(context, signal_number):
    probe = _Probe(context, {'/joint_states': JointState})
    player = _player(GOLDEN, '--loop', '--rate', '20')
    try:
        wait_for(lambda: len(probe.order) > 10, 30.0, 'the playback under way')
        assert stop_process(player, signal_number, 20.0) == exit_codes.EXIT_OK
        assert 'Traceback' not in player.stderr.read()
    finally:
        stop_process(player)
        probe.close()


def _profile_yaml(reliability, durability, depth=0, history='unknown'):
    return (f'- history: {history}\n  depth: {depth}\n  reliability: {reliability}\n'
            f'  durability: {durability}')


def test_the_played_qos_is_what_every_recorded_publisher_offered():
    both = _profile_yaml('reliable', 'transient_local', 5, 'keep_last') + '\n' + _profile_yaml(
        'reliable', 'transient_local', 20, 'keep_last')
    qos = played_qos(both)
    assert (qos.reliability, qos.durability, qos.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL, 20)
    mixed = '\n'.join([_profile_yaml('reliable', 'volatile'),
                       _profile_yaml('best_effort', 'volatile')])
    qos = played_qos(mixed)
    assert qos.reliability == ReliabilityPolicy.BEST_EFFORT and qos.depth == 1000
    for unknown in ('', '[]', 'not: [yaml', '42'):
        qos = played_qos(unknown)
        assert (qos.reliability, qos.durability) == (ReliabilityPolicy.BEST_EFFORT,
                                                     DurabilityPolicy.VOLATILE)
