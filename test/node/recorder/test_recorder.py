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
The MCAP recorder against real processes and DDS, checked with independent readers.

The recorder runs as its own process next to a publisher (the real shaper_sim when it is
installed, else stand_in_publisher.py, which waits for its subscribers so counts match
exactly) and a parallel rclpy subscriber in this process. Files are read back with mcap +
mcap-ros2-support, with rosbags (its MCAP storage reader, and AnyReader on a rosbag2 folder
made from the file's own rosbag2 record), and with qrm_ros.recording.bag_reader.
"""

import dataclasses
import importlib.util
import json
import os
import resource
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
import types

from ament_index_python.packages import get_package_share_directory
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from qrm_ros.recording.bag_reader import open_run, RunFileError
from qrm_ros.recording.mcap_recover import RECOVERY_METADATA, recovered_losses
from qrm_ros.core.kinematics.geometry import Geometry
import yaml

from ros_probe import BackgroundSpinner, call, installed_executable, stop_process, wait_for
from repo_paths import TEST_FOLDER

PUBLISHER = os.path.join(TEST_FOLDER, 'stand_in_publisher.py')
REAL_SIM = importlib.util.find_spec('qrm_ros.node.shaper_sim.shaper_sim') is not None
TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
         '/ram/twist': 'geometry_msgs/msg/TwistStamped',
         '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
         '/input_speed_cmd': 'std_msgs/msg/Float64',
         '/parameter_events': 'rcl_interfaces/msg/ParameterEvent'}
# What the recorder adds once it knows the sim's geometry (only the real sim says it).
MACHINE_TYPES = {'/robot_description': 'std_msgs/msg/String',
                 '/tf_static': 'tf2_msgs/msg/TFMessage', '/tf': 'tf2_msgs/msg/TFMessage'}
QOS_FIELDS = {'history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
              'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions'}
GEOMETRY = list(Geometry.field_names())


def _recorder_executable():
    executable = installed_executable('mcap_recorder')
    return [executable] if executable else [sys.executable, '-m', 'qrm_ros.cli.mcap_recorder']


def _recorder_command(*parameters):
    command = _recorder_executable() + ['--ros-args']
    for parameter in parameters:
        command += ['-p', parameter]
    return command


def _publisher_command(count, rate, subscribers, forever=False):
    if REAL_SIM:
        return [installed_executable('shaper_sim') or 'shaper_sim']
    return [sys.executable, PUBLISHER, str(count), str(rate), str(subscribers)] + (
        ['--forever'] if forever else [])


class Process:
    """A child process with its output in files, stopped by pid only."""

    started = []  # every one, so a failing test leaves none running (see no_leftovers)

    def __init__(self, command, folder, name, **kwargs):
        self.out_path = os.path.join(folder, name + '.out')
        self.err_path = os.path.join(folder, name + '.err')
        with open(self.out_path, 'w') as out, open(self.err_path, 'w') as err:
            self.popen = subprocess.Popen(command, stdout=out, stderr=err, **kwargs)
        Process.started.append(self)

    def output(self):
        with open(self.out_path) as out, open(self.err_path) as err:
            return out.read() + err.read()

    def wait_for_output(self, text, timeout):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.output():
                return True
            if self.popen.poll() is not None:
                return text in self.output()
            time.sleep(0.05)
        return False

    def stop(self, number=signal.SIGINT, timeout=10.0, check=True):
        """Stop it (SIGINT, then kill); fail if it had to be killed, unless not check."""
        try:
            return stop_process(self.popen, number, timeout)
        except AssertionError as error:
            if check:
                raise AssertionError(f'{error}:\n{self.output()}') from None
            return self.popen.returncode

    def exit_code(self, timeout=15.0):
        return self.popen.wait(timeout)


@pytest.fixture(autouse=True)
def no_leftovers():
    """Kill what a test started and did not stop (e.g. it failed before its finally)."""
    yield
    while Process.started:
        popen = Process.started.pop().popen
        if popen.poll() is None:
            popen.kill()
            popen.wait()


class Listener:
    """An rclpy node in this process that takes every message of the run, raw."""

    def __init__(self):
        import rclpy
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rcl_interfaces.srv import GetParameters, SetParameters
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('recorder_test_listener', context=self.context)
        self.received = {topic: [] for topic in TYPES}
        self.lock = threading.Lock()
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for topic, type_name in TYPES.items():
            message_class = _message_class(type_name)
            self.node.create_subscription(
                message_class, topic, lambda data, topic=topic: self._take(topic, data), qos,
                raw=True)
        self.get_client = self.node.create_client(GetParameters, '/shaper_sim/get_parameters')
        self.set_client = self.node.create_client(SetParameters, '/shaper_sim/set_parameters')
        self.spinner = BackgroundSpinner(self.context, self.node)

    def _take(self, topic, data):
        with self.lock:
            self.received[topic].append((time.time_ns(), data))

    def messages(self, topic):
        with self.lock:
            return [data for _, data in self.received[topic]]

    def wait_quiet(self, quiet=0.4, timeout=10.0):
        deadline = time.monotonic() + timeout
        last, since = None, time.monotonic()
        while time.monotonic() < deadline:
            with self.lock:
                counts = tuple(len(v) for v in self.received.values())
            if counts != last:
                last, since = counts, time.monotonic()
            elif time.monotonic() - since > quiet:
                return
            time.sleep(0.05)

    def call(self, client, request, timeout=5.0):
        return call(client, request, timeout)

    def close(self):
        self.spinner.stop()
        self.node.destroy_node()
        self.context.try_shutdown()


def _message_class(type_name):
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(package + '.msg'), name)


@pytest.fixture
def listener():
    node = Listener()
    yield node
    node.close()


def _plain(value):
    """Nested plain Python data of a message from rclpy, mcap_ros2 or rosbags."""
    if hasattr(value, 'get_fields_and_field_types'):
        return {k: _plain(getattr(value, k)) for k in value.get_fields_and_field_types()}
    if isinstance(value, bytes):  # rclpy spells 'byte' fields as bytes, the others as int
        return value[0] if len(value) == 1 else list(value)
    if isinstance(value, (str, bool, int, float)) or value is None:
        return value
    if dataclasses.is_dataclass(value):  # rosbags: constants are the fields with a default
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if f.default is dataclasses.MISSING}
    if hasattr(value, 'tolist'):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)) or hasattr(value, '__iter__'):
        return [_plain(v) for v in value]
    return {k: _plain(getattr(value, k)) for k in value.__slots__}


def _expected_definition(type_name):
    """rosbag2's full text built here from the .msg files, dependencies from rosbags' store."""
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)

    def msg_text(name):
        package, _, short = name.split('/')
        with open(os.path.join(get_package_share_directory(package), 'msg', short + '.msg'),
                  newline='') as handle:
            return handle.read()

    def nested(name):
        names = set()
        for _, (kind, detail) in store.fielddefs[name][1]:
            if kind.name == 'NAME':
                names.add(detail)
            elif kind.name in ('ARRAY', 'SEQUENCE') and detail[0][0].name == 'NAME':
                names.add(detail[0][1])
        return sorted(n.replace('/msg/', '/') for n in names)

    seen = set()

    def build(name):
        text = msg_text(name)
        for dependency in nested(name):
            if dependency not in seen:
                seen.add(dependency)
                text += '\n' + '=' * 80 + '\nMSG: ' + dependency + '\n'
                text += build(dependency.replace('/', '/msg/'))
        return text
    return build(type_name)


def _read_with_mcap(path):
    with open(path, 'rb') as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        decoded = {}
        for schema, channel, message, value in reader.iter_decoded_messages(
                log_time_order=True):
            decoded.setdefault(channel.topic, []).append((message, value))
    return header, summary, decoded


def _read_with_rosbags(path):
    from pathlib import Path
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.typesys import get_typestore, get_types_from_msg, Stores
    storage = McapReader(Path(path))
    storage.open()
    try:
        store = get_typestore(Stores.EMPTY)
        for connection in storage.connections:
            store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        messages = {}
        for connection, timestamp, data in storage.messages(storage.connections):
            messages.setdefault(connection.topic, []).append(
                (timestamp, data, store.deserialize_cdr(data, connection.msgtype)))
        return list(storage.connections), messages
    finally:
        storage.close()


def _check_one_line_error(process, exit_code, *fragments):
    """One 'mcap_recorder: error:' line holding each fragment, no traceback, this exit code."""
    text = process.output()
    assert process.popen.returncode == exit_code, text
    assert 'Traceback' not in text, text
    errors = [line for line in text.splitlines() if line.startswith('mcap_recorder: error:')]
    assert len(errors) == 1, text
    for fragment in fragments:
        assert fragment in errors[0], text
    return errors[0]


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """
    One real run, recorded once for the focused tests below.

    The recorder runs next to a publisher and the parallel listener; a speed command burst
    and a parameter change are sent while it records. The listener is closed before the
    tests run, so other tests' stand-in publishers count their subscribers right.
    """
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import GetParameters, SetParameters
    from std_msgs.msg import Float64
    folder = tmp_path_factory.mktemp('recording')
    output = str(folder / 'runs' / 'nested' / 'run.mcap')
    listener = Listener()
    recorder = Process(_recorder_command(f'output:={output}', 'max_chunk_duration:=0.5'),
                       str(folder), 'recorder')
    publisher = Process(_publisher_command(300, 100.0, 2), str(folder), 'publisher')
    speeds = [3.0, 3.5, 4.0, 4.5, 5.0]
    try:
        command = listener.node.create_publisher(Float64, 'input_speed_cmd', 10)
        wait_for(lambda: command.get_subscription_count() >= 3, 15.0,
                 'input_speed_cmd subscribers (sim, recorder, listener)')
        for speed in speeds:
            command.publish(Float64(data=speed))
            time.sleep(0.05)
        # Set a parameter only once the recorder has talked to the sim (so their endpoints
        # have discovered each other): a volatile event sent earlier is nobody's to record.
        assert recorder.wait_for_output('parameters of /shaper_sim', 15.0), recorder.output()
        request = SetParameters.Request()
        request.parameters = [Parameter(name='coupling_offset', value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE, double_value=0.012))]
        assert listener.call(listener.set_client, request).results[0].successful
        wait_for(lambda: any(b'coupling_offset' in data for data in listener.messages(
            '/parameter_events')), 5.0, 'the coupling_offset parameter event')
        request = GetParameters.Request()
        request.names = GEOMETRY
        geometry = [v.double_value for v in listener.call(listener.get_client, request).values]
        if REAL_SIM:  # it reports a stroke pair about once per input turn: wait for two
            wanted = len(listener.messages('/diagnostics')) + 2
            wait_for(lambda: len(listener.messages('/diagnostics')) >= wanted, 10.0,
                     'two more stroke-pair diagnostics')
        else:
            assert publisher.wait_for_output('published 300', 15.0), publisher.output()
            listener.wait_quiet()  # the stand-in is idle now; the real sim keeps publishing
        exit_code = recorder.stop()
        sent = {topic: listener.messages(topic) for topic in TYPES}
    finally:
        publisher.stop(check=False)
        recorder.stop(check=False)
        listener.close()
    assert exit_code == 0, recorder.output()
    run = open_run(output)
    ours = {}
    for message in run.messages():
        ours.setdefault(message[0], []).append(message)
    return types.SimpleNamespace(
        output=output, folder=folder, log=recorder.output(), sent=sent, speeds=speeds,
        geometry=geometry, run=run, ours=ours, mcap=_read_with_mcap(output),
        rosbags=_read_with_rosbags(output))


def _common_part(topic, sent, recorded):
    """The recorded and sent messages from the first one both hold (both matched late)."""
    if REAL_SIM and topic != '/input_speed_cmd':
        # The real sim publishes at once: the recorder and the listener each match it after
        # their own discovery. From the first message both hold, they must agree.
        common = set(sent)
        skipped = next(i for i, data in enumerate(recorded) if data in common)
        start = sent.index(recorded[skipped])
        assert 0 in (skipped, start), topic
        return sent[start:start + len(recorded) - skipped], recorded[skipped:]
    return sent, recorded


def test_recording_is_finished_with_summary_statistics_and_indexes(recording):
    header, summary, decoded = recording.mcap
    assert header.profile == 'ros2'
    assert not recording.run.truncated and recording.run.problem is None
    assert 'Traceback' not in recording.log
    assert summary.statistics.message_count == sum(len(v) for v in decoded.values())
    assert summary.chunk_indexes and all(c.message_index_offsets for c in summary.chunk_indexes)
    for channel in summary.channels.values():
        assert summary.statistics.channel_message_counts.get(channel.id, 0) == len(
            decoded.get(channel.topic, []))


@pytest.mark.parametrize('topic', sorted(TYPES))
def test_channel_schema_and_qos_metadata_are_rosbag2s(recording, topic):
    _, summary, _ = recording.mcap
    by_topic = {c.topic: c for c in summary.channels.values()}
    assert topic in by_topic, sorted(by_topic)
    channel = by_topic[topic]
    schema = summary.schemas[channel.schema_id]
    assert (channel.message_encoding, schema.encoding, schema.name) == (
        'cdr', 'ros2msg', TYPES[topic])
    # Schema text exactly as rosbag2 builds it, built here independently.
    assert schema.data.decode() == _expected_definition(TYPES[topic])
    # QoS metadata: YAML, every field rosbag2 writes, the publishers' actual offer.
    profiles = yaml.safe_load(channel.metadata['offered_qos_profiles'])
    assert profiles and all(set(p) == QOS_FIELDS for p in profiles), profiles
    assert all(p['reliability'] == 'reliable' and p['durability'] == 'volatile'
               and set(p['deadline']) == {'sec', 'nsec'} for p in profiles), profiles
    assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
    assert recording.run.topics()[topic] == TYPES[topic]
    connections, _ = recording.rosbags
    (connection,) = [c for c in connections if c.topic == topic]
    assert connection.ext.offered_qos_profiles


def test_times_are_receive_and_source_times_in_order(recording):
    log_times = []
    for topic, schema_name, log_ns, publish_ns, _ in recording.run.messages():
        log_times.append(log_ns)
        assert schema_name == {**TYPES, **MACHINE_TYPES}[topic]
        assert 0 <= log_ns - publish_ns < 1_000_000_000  # sent, then received, same clock
    assert log_times == sorted(log_times)


@pytest.mark.parametrize('topic', ['/joint_states', '/ram/twist', '/diagnostics',
                                   '/input_speed_cmd'])
def test_recorded_bytes_are_what_a_parallel_subscriber_received(recording, topic):
    recorded = [m[4] for m in recording.ours.get(topic, [])]
    assert recorded, topic
    sent, recorded = _common_part(topic, recording.sent[topic], recorded)
    assert len(recorded) == len(sent) and recorded == sent


@pytest.mark.parametrize('topic', ['/joint_states', '/ram/twist', '/diagnostics',
                                   '/input_speed_cmd', '/parameter_events'])
def test_independent_readers_decode_the_same_values_as_rclpy(recording, topic):
    import rclpy.serialization
    _, _, mcap_decoded = recording.mcap
    _, rosbags_messages = recording.rosbags
    recorded = [m[4] for m in recording.ours[topic]]
    assert [m.data for m, _ in mcap_decoded[topic]] == recorded
    assert [d for _, d, _ in rosbags_messages[topic]] == recorded
    message_class = _message_class(TYPES[topic])
    for data, (_, from_mcap), (_, _, from_rosbags) in zip(
            recorded, mcap_decoded[topic], rosbags_messages[topic]):
        expected = _plain(rclpy.serialization.deserialize_message(data, message_class))
        assert _plain(from_mcap) == expected
        assert _plain(from_rosbags) == expected


def test_the_machine_is_recorded_from_the_first_joint_state_once_the_geometry_is_known(
        recording):
    from rosbags.typesys import get_typestore, Stores
    from qrm_ros.recording.machine_transforms import moving_transforms
    from qrm_ros.recording.urdf_model import urdf_text
    topics = recording.run.topics()
    if not REAL_SIM:  # the stand-in has no geometry to tell: nothing of the machine
        assert not set(MACHINE_TYPES) & set(topics)
        return
    assert {topic: topics.get(topic) for topic in MACHINE_TYPES} == MACHINE_TYPES
    store = get_typestore(Stores.ROS2_JAZZY)
    geometry = Geometry(*recording.geometry)
    joint_states = recording.ours['/joint_states']
    (description,) = recording.ours['/robot_description']
    (static,) = recording.ours['/tf_static']
    assert description[2] == static[2] == joint_states[0][2]
    assert store.deserialize_cdr(description[4], 'std_msgs/msg/String').data == urdf_text(
        geometry)
    transforms = recording.ours['/tf']
    assert len(transforms) == len(joint_states)
    for joint_state, transform in zip(joint_states, transforms):
        assert transform[2] == joint_state[2]
        decoded = store.deserialize_cdr(joint_state[4], 'sensor_msgs/msg/JointState')
        values = dict(zip(decoded.name, decoded.position))
        tf = store.deserialize_cdr(transform[4], 'tf2_msgs/msg/TFMessage').transforms
        assert [(t.header.stamp, t.child_frame_id, t.transform.translation.y)
                for t in tf] == [(decoded.header.stamp, m.child, m.translation[1])
                                 for m in moving_transforms(geometry, values)]
    assert 'recording the machine' in recording.log


def test_speed_commands_and_the_parameter_change_are_recorded(recording):
    _, _, mcap_decoded = recording.mcap
    assert [_plain(v)['data'] for _, v in mcap_decoded['/input_speed_cmd']] == recording.speeds
    events = [v for _, v in mcap_decoded['/parameter_events']]
    assert any(e.node == '/shaper_sim' and any(
        p.name == 'coupling_offset' and p.value.double_value == 0.012
        for p in e.changed_parameters) for e in events)


def test_run_metadata_holds_the_geometry_and_all_parameters(recording):
    metadata = recording.run.metadata
    geometry = recording.geometry
    assert [float(metadata['qrm_ros.geometry'][n]) for n in GEOMETRY] == geometry
    assert [metadata['qrm_ros.geometry'][n] for n in GEOMETRY] == [repr(g) for g in geometry]
    parameters = {k: json.loads(v) for k, v in metadata['qrm_ros.parameters'].items()}
    assert [parameters[n] for n in GEOMETRY] == geometry
    assert parameters['coupling_offset'] in (0.01, 0.012) or REAL_SIM


def _anyreader_counts(path, folder):
    """Messages per topic from rosbags' AnyReader on a rosbag2 folder of the file's record."""
    from pathlib import Path
    from rosbags.highlevel import AnyReader
    run = open_run(path)
    bag = folder / 'bag'
    bag.mkdir()
    metadata = yaml.safe_load(run.metadata['rosbag2']['serialized_metadata'])
    (bag / 'metadata.yaml').write_text(yaml.safe_dump(
        {'rosbag2_bagfile_information': metadata}))
    os.symlink(os.path.abspath(path), bag / metadata['relative_file_paths'][0])
    with AnyReader([Path(bag)]) as reader:
        counts = {}
        for connection, _, data in reader.messages(connections=reader.connections):
            reader.deserialize(data, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    assert metadata['message_count'] == sum(counts.values())
    return counts


def test_rosbags_anyreader_opens_the_folder_its_rosbag2_record_describes(recording):
    counts = _anyreader_counts(recording.output, recording.folder)
    assert counts == {t: len(v) for t, v in recording.ours.items()}


def _record_a_publisher(folder, *parameters):
    """Start a recorder (these parameters) and a publisher at 100 Hz until stopped."""
    output = str(folder / 'run.mcap')
    recorder = Process(_recorder_command(f'output:={output}', *parameters), str(folder),
                       'recorder')
    publisher = Process(_publisher_command(0, 100.0, 2, forever=True), str(folder),
                        'publisher')
    return output, recorder, publisher


def test_sigterm_finishes_the_file(tmp_path, listener):
    output, recorder, publisher = _record_a_publisher(tmp_path, 'compression:=lz4')
    try:
        wait_for(lambda: len(listener.messages('/joint_states')) >= 100, 15.0,
                 '100 joint states at the listener')
        assert recorder.stop(signal.SIGTERM) == 0, recorder.output()
    finally:
        publisher.stop()
    run = open_run(output)
    assert not run.truncated and run.problem is None
    with open(output, 'rb') as handle:
        summary = make_reader(handle).get_summary()
    assert summary.statistics.message_count == sum(1 for _ in run.messages()) > 0
    assert {c.compression for c in summary.chunk_indexes} == {'lz4'}


def test_sigkill_loses_at_most_one_chunk_and_recover_finishes_the_file(tmp_path, listener):
    from sensor_msgs.msg import JointState
    import rclpy.serialization
    chunk_duration = 0.3
    output, recorder, publisher = _record_a_publisher(
        tmp_path, f'max_chunk_duration:={chunk_duration}')
    try:
        wait_for(lambda: len(listener.messages('/joint_states')) >= 150, 15.0,
                 '150 joint states at the listener')
        # On a loaded machine the recorder may match the publisher well after the listener:
        # kill it only once a chunk of joint states is on disk.
        wait_for(lambda: os.path.exists(output) and next(
            open_run(output).messages(['joint_states']), None) is not None,
            15.0, 'a chunk of joint states in the file')
        killed_ns = time.time_ns()
        recorder.stop(signal.SIGKILL)
    finally:
        publisher.stop()
    run = open_run(output)
    assert run.truncated and 'not finished' in run.problem
    recorded = [d for _, _, _, _, d in run.messages(['joint_states'])]
    sent = listener.messages('/joint_states')
    # Both matched the publisher after their own discovery; compare from the first common one.
    common = set(sent)
    recorded = recorded[next(i for i, data in enumerate(recorded) if data in common):]
    assert recorded and recorded == sent[sent.index(recorded[0]):][:len(recorded)]

    def stamp_ns(data):
        stamp = rclpy.serialization.deserialize_message(data, JointState).header.stamp
        return stamp.sec * 1_000_000_000 + stamp.nanosec
    lost = [d for d in sent[sent.index(recorded[-1]) + 1:] if stamp_ns(d) < killed_ns]
    if lost:
        span = killed_ns - stamp_ns(lost[0])
        # One chunk plus the 30 ms chunk timer and scheduling slack on a loaded machine.
        assert span <= (chunk_duration + 0.15) * 1e9, span / 1e9
    _check_recovered(output, tmp_path)


def _recover(broken, fixed, folder, name='recover'):
    process = Process(_recorder_executable() + ['--recover', str(broken), str(fixed)],
                      str(folder), name)
    process.exit_code()
    return process


def _by_time(message):
    return message[1], message[0], message[2]


def _check_recovered(broken, folder):
    """Recover a broken file; rosbags reads back exactly what bag_reader reads of it."""
    from pathlib import Path
    from rosbags.rosbag2.storage_mcap import McapReader
    fixed = folder / 'fixed.mcap'
    process = _recover(broken, fixed, folder)
    assert process.popen.returncode == 0, process.output()
    assert 'Traceback' not in process.output()
    readable = open_run(broken)
    expected = [(m[0], m[2], m[4]) for m in readable.messages()]
    assert f'recovered {len(expected)} messages into {fixed}' in process.output()
    storage = McapReader(Path(fixed))
    storage.open()
    try:
        got = [(c.topic, t, d) for c, t, d in storage.messages(storage.connections)]
    finally:
        storage.close()
    # rosbags yields in log-time order, bag_reader in file order: compare as sets in order.
    assert sorted(got, key=_by_time) == sorted(expected, key=_by_time) and expected
    recovered = open_run(fixed)
    assert not recovered.truncated and recovered.problem is None
    # The file's own metadata is kept; the recovery adds what it lost, said once more.
    assert {k: v for k, v in recovered.metadata.items()
            if k not in ('rosbag2', RECOVERY_METADATA)} == {
        k: v for k, v in readable.metadata.items() if k != 'rosbag2'}
    warnings = [line.split('warning: ', 1)[1] for line in process.output().splitlines()
                if line.startswith('mcap_recorder: warning: ')]
    assert recovered_losses(recovered.metadata) == warnings
    with open(fixed, 'rb') as handle:
        summary = make_reader(handle).get_summary()
    assert summary.statistics.message_count == len(expected)
    counts = {}
    for topic, _, _ in expected:
        counts[topic] = counts.get(topic, 0) + 1
    assert {summary.channels[i].topic: n for i, n in
            summary.statistics.channel_message_counts.items()} == counts
    assert _anyreader_counts(fixed, folder) == counts
    return process


def test_recover_keeps_the_whole_chunks_of_a_file_cut_mid_chunk(recording, tmp_path):
    with open(recording.output, 'rb') as handle:
        chunks = make_reader(handle).get_summary().chunk_indexes
    assert len(chunks) >= 3
    middle = chunks[len(chunks) // 2]
    cut = tmp_path / 'cut.mcap'
    with open(recording.output, 'rb') as handle:
        cut.write_bytes(handle.read(middle.chunk_start_offset + middle.chunk_length // 2))
    process = _check_recovered(cut, tmp_path)
    assert 'warning: the last' in process.output() and 'are not readable' in process.output()


def test_recover_skips_a_damaged_chunk_says_which_and_keeps_the_rest(tmp_path):
    path = tmp_path / 'full.mcap'
    ends = _synthetic_run(path)
    data = bytearray(path.read_bytes()[:ends[3] + 10])  # four whole chunks and a bit
    inside = ends[0] + 100  # the second chunk's compressed records
    data[inside:inside + 8] = b'\xff' * 8
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(bytes(data))
    fixed = tmp_path / 'fixed.mcap'
    process = _recover(damaged, fixed, tmp_path)
    assert process.popen.returncode == 0, process.output()
    # Messages 20..39 were in the damaged chunk (log times 1020..1039); 0..19, 40..79 remain.
    assert 'lost a damaged chunk holding log time 1020 to 1039 ns' in process.output()
    assert 'recovered 60 messages' in process.output()
    with open(fixed, 'rb') as handle:
        values = [m.data for _, _, m in make_reader(handle).iter_messages()]
    assert values == [i.to_bytes(4, 'little') for i in list(range(20)) + list(range(40, 80))]


@pytest.mark.parametrize('case', ['missing input', 'existing output', 'not mcap'])
def test_recover_refuses_bad_requests_with_one_line(tmp_path, case):
    broken, fixed = tmp_path / 'broken.mcap', tmp_path / 'fixed.mcap'
    if case != 'missing input':
        broken.write_bytes(b'not an mcap file at all')
    if case == 'existing output':
        fixed.write_bytes(b'precious')
    process = _recover(broken, fixed, tmp_path)
    words = {'missing input': ['does not exist'], 'existing output': ['already exists'],
             'not mcap': ["is not an MCAP file (it starts with b'not an m', not the MCAP "
                          'magic bytes and header); nothing to recover']}[case]
    _check_one_line_error(process, 2, *words)  # unusable input: 2, as every command
    if case == 'existing output':
        assert fixed.read_bytes() == b'precious'
    else:
        assert not fixed.exists()


def test_existing_output_is_refused_as_a_configuration_error(tmp_path):
    output = tmp_path / 'run.mcap'
    output.write_bytes(b'precious')
    recorder = Process(_recorder_command(f'output:={output}'), str(tmp_path), 'recorder')
    recorder.exit_code()
    _check_one_line_error(recorder, 2, 'already exists', str(output))
    assert output.read_bytes() == b'precious'


@pytest.mark.parametrize('parameter, words', [
    ('max_chunk_duration:=0.0', ['max_chunk_duration=0.0', '[0.001, 3600] s']),
    ('sim_wait_timeout:=-1.0', ['sim_wait_timeout=-1.0', '[0, 3600] s']),
    ('compression:=gzip', ["compression='gzip'", 'zstd, lz4, none']),
    ('topics:=5', ['topics']),
    # A pattern is no topic name: it was a traceback, exit 1 and a 50-byte stub file that
    # then blocked a rerun ("already exists").
    ("topics:=['/joint_.*']", ["parameter topics: '/joint_.*' is not a ROS topic name",
                               'topics are names, not patterns']),
])
def test_bad_settings_are_refused_naming_the_allowed_values(tmp_path, parameter, words):
    output = tmp_path / 'run.mcap'
    recorder = Process(_recorder_command(f'output:={output}', parameter), str(tmp_path),
                       'recorder')
    recorder.exit_code()
    _check_one_line_error(recorder, 2, *words)
    assert not output.exists()


@pytest.mark.parametrize('arguments, words', [
    (['--ros-args', '-p'], ['parse ROS arguments']),
    (['--record-everything'], ['unrecognized arguments: --record-everything']),
    (['--recover', 'only_one.mcap'], ['--recover: expected 2 arguments']),
])
def test_usage_errors_exit_2_with_one_line(tmp_path, arguments, words):
    recorder = Process(_recorder_executable() + arguments, str(tmp_path), 'recorder')
    recorder.exit_code()
    _check_one_line_error(recorder, 2, *words)


def test_unwritable_output_is_a_failure_with_one_clear_line(tmp_path):
    blocker = tmp_path / 'not_a_folder'
    blocker.write_text('')
    output = blocker / 'run.mcap'
    recorder = Process(_recorder_command(f'output:={output}'), str(tmp_path), 'recorder')
    recorder.exit_code()
    _check_one_line_error(recorder, 1, 'cannot create output', str(output))
    if os.geteuid() != 0:  # root writes anywhere, so only a normal user can check permissions
        locked = tmp_path / 'locked'
        locked.mkdir(mode=0o500)
        recorder = Process(_recorder_command(f'output:={locked / "run.mcap"}'),
                           str(tmp_path), 'recorder2')
        recorder.exit_code()
        _check_one_line_error(recorder, 1, 'Permission denied')


def _can_mount_tmpfs():
    if not shutil.which('unshare'):
        return False
    probe = subprocess.run(['unshare', '-rm', 'sh', '-c', 'mount -t tmpfs -o size=16k tmpfs '
                            '/mnt'], capture_output=True)
    return probe.returncode == 0


def test_a_full_disk_at_start_leaves_no_file_and_says_what_to_do(tmp_path):
    """A real ENOSPC: a 64 KiB tmpfs filled up, in a user and mount namespace of its own."""
    if not _can_mount_tmpfs():
        pytest.skip('cannot mount a tmpfs in a user namespace here (unshare -rm)')
    disk = tmp_path / 'disk'
    disk.mkdir()
    recorder = ' '.join(shlex.quote(a) for a in _recorder_command(
        f'output:={disk / "runs" / "run.mcap"}'))
    script = (f'mount -t tmpfs -o size=64k tmpfs {disk} && mkdir {disk}/runs && '
              f'(dd if=/dev/zero of={disk}/filler bs=4k 2>/dev/null; true) && '
              f'{recorder}; code=$?; echo "left: $(ls -A {disk}/runs)"; exit $code')
    process = Process(['unshare', '-rm', 'sh', '-c', script], str(tmp_path), 'recorder')
    process.exit_code(30)
    _check_one_line_error(process, 1, 'No space left on device', 'no file was left',
                          'free space')
    assert 'left: \n' in process.output(), process.output()  # nothing in runs/


def test_full_disk_while_recording_stops_with_one_line_and_keeps_what_was_written(tmp_path):
    limit = 96_000  # past the schemas, the metadata and the URDF: the disk fills mid-run

    def small_disk():
        # A file size limit makes writes fail like a full disk (EFBIG instead of ENOSPC).
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    output = str(tmp_path / 'run.mcap')
    recorder = Process(_recorder_command(f'output:={output}', 'compression:=none',
                                         'max_chunk_duration:=0.2'),
                       str(tmp_path), 'recorder', preexec_fn=small_disk)
    publisher = Process(_publisher_command(0, 100.0, 1, forever=True), str(tmp_path),
                        'publisher')
    try:
        recorder.exit_code(30)
    finally:
        publisher.stop()
    _check_one_line_error(recorder, 1, 'cannot write', output, 'errno', '--recover',
                          'free space')
    run = open_run(output)
    assert run.truncated and os.path.getsize(output) <= limit
    assert sum(1 for _ in run.messages(['/joint_states'])) > 0


# --- bag_reader on its own ------------------------------------------------------------------

def _synthetic_run(path, chunks=5, per_chunk=20):
    from mcap.writer import CompressionType, Writer
    with open(path, 'wb') as handle:
        writer = Writer(handle, chunk_size=1 << 40, compression=CompressionType.ZSTD)
        writer.start('ros2', 'test')
        schema = writer.register_schema('std_msgs/msg/Float64', 'ros2msg', b'float64 data\n')
        channel = writer.register_channel('/x', 'cdr', schema)
        writer.add_metadata('qrm_ros.geometry', {'ram_height': '0.2'})
        ends = []
        for index in range(chunks * per_chunk):
            writer.add_message(channel, 1000 + index, index.to_bytes(4, 'little'), 500 + index)
            if index % per_chunk == per_chunk - 1:
                writer.flush()
                ends.append(handle.tell())
        writer.finish()
    return ends


def test_reader_errors_are_one_clear_exception(tmp_path):
    with pytest.raises(RunFileError, match='does not exist'):
        open_run(tmp_path / 'missing.mcap')
    text = tmp_path / 'notes.mcap'
    text.write_text('hello')
    with pytest.raises(RunFileError, match='not an MCAP file'):
        open_run(text)
    assert issubclass(RunFileError, ValueError)


def test_reader_reads_unfinished_files_up_to_the_last_whole_chunk(tmp_path):
    path = tmp_path / 'full.mcap'
    ends = _synthetic_run(path)
    whole = open_run(path)
    assert not whole.truncated and whole.metadata == {'qrm_ros.geometry': {'ram_height': '0.2'}}
    assert [(m[2], m[3], m[4]) for m in whole.messages()] == [
        (1000 + i, 500 + i, i.to_bytes(4, 'little')) for i in range(100)]
    assert whole.topics() == {'/x': 'std_msgs/msg/Float64'}
    data = path.read_bytes()
    # Cut inside the first chunk, at chunk boundaries, inside a chunk, in DataEnd, in the
    # summary: every whole chunk before the cut is read, nothing after it.
    for cut in sorted({30, ends[0], ends[1] + 5, ends[2], ends[-1] + 3, len(data) - 40}):
        part = tmp_path / f'cut{cut}.mcap'
        part.write_bytes(data[:cut])
        run = open_run(part)
        complete = sum(1 for end in ends if end <= cut)
        assert run.truncated and run.problem, cut
        assert [m[4] for m in run.messages(['x'])] == [
            i.to_bytes(4, 'little') for i in range(complete * 20)], cut


def test_reader_stops_at_a_damaged_chunk_of_an_unfinished_file(tmp_path):
    path = tmp_path / 'full.mcap'
    ends = _synthetic_run(path)
    data = bytearray(path.read_bytes()[:ends[2]])  # three whole chunks, no summary
    inside = ends[0] + 100  # the second chunk's compressed records (its index follows them)
    data[inside:inside + 8] = b'\xff' * 8
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(bytes(data))
    run = open_run(damaged)
    assert run.truncated and 'damaged' in run.problem
    assert [m[4] for m in run.messages()] == [i.to_bytes(4, 'little') for i in range(20)]
