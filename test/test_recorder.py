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
made from the file's own rosbag2 record), and with qrm_ros.bag_reader.
"""

import dataclasses
import importlib.util
import json
import os
import resource
import signal
import subprocess
import sys
import threading
import time

from ament_index_python.packages import get_package_share_directory
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from qrm_ros.bag_reader import open_run, RunFileError
import yaml

from ros_probe import BackgroundSpinner, call, installed_executable, wait_for

HERE = os.path.dirname(os.path.abspath(__file__))
PUBLISHER = os.path.join(HERE, 'stand_in_publisher.py')
REAL_SIM = importlib.util.find_spec('qrm_ros.shaper_sim') is not None
TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
         '/ram/twist': 'geometry_msgs/msg/TwistStamped',
         '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
         '/input_speed_cmd': 'std_msgs/msg/Float64',
         '/parameter_events': 'rcl_interfaces/msg/ParameterEvent'}
QOS_FIELDS = {'history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
              'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions'}
GEOMETRY = ['coupling_radius', 'crank_radius', 'pivot_distance', 'ram_height', 'crank_phase']


def _recorder_command(*parameters):
    executable = installed_executable('mcap_recorder')
    command = [executable] if executable else [sys.executable, '-m', 'qrm_ros.recorder']
    command += ['--ros-args']
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

    def stop(self, number=signal.SIGINT, timeout=10.0):
        if self.popen.poll() is None:
            self.popen.send_signal(number)
        try:
            return self.popen.wait(timeout)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
            raise AssertionError(f'{self.popen.args[0]} ignored signal {number}:\n'
                                 + self.output())


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


def _check_one_line_error(process, *fragments):
    text = process.output()
    assert process.popen.returncode not in (0, None), text
    assert 'Traceback' not in text, text
    errors = [line for line in text.splitlines() if line.startswith('mcap_recorder: error:')]
    assert len(errors) == 1, text
    for fragment in fragments:
        assert fragment in errors[0], text
    return errors[0]


def test_real_run_matches_parallel_subscriber_and_independent_readers(tmp_path, listener):
    import rclpy.serialization
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import GetParameters, SetParameters
    from std_msgs.msg import Float64
    output = str(tmp_path / 'runs' / 'nested' / 'run.mcap')
    recorder = Process(_recorder_command(f'output:={output}', 'max_chunk_duration:=0.5'),
                       str(tmp_path), 'recorder')
    publisher = Process(_publisher_command(300, 100.0, 2), str(tmp_path), 'publisher')
    try:
        command = listener.node.create_publisher(Float64, 'input_speed_cmd', 10)
        wait_for(lambda: command.get_subscription_count() >= 3, 15.0,
                 'input_speed_cmd subscribers (sim, recorder, listener)')
        speeds = [3.0, 3.5, 4.0, 4.5, 5.0]
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
        if not REAL_SIM:
            listener.wait_quiet()  # the stand-in is idle now; the real sim keeps publishing
        assert recorder.stop() == 0, recorder.output()
    finally:
        assert publisher.stop() in (0, -signal.SIGINT), publisher.output()
    assert 'Traceback' not in recorder.output()

    header, summary, mcap_decoded = _read_with_mcap(output)
    connections, rosbags_messages = _read_with_rosbags(output)
    run = open_run(output)
    assert header.profile == 'ros2'
    assert not run.truncated and run.problem is None
    # Summary, statistics and indexes are there and agree with the messages.
    assert summary.statistics.message_count == sum(len(v) for v in mcap_decoded.values())
    assert summary.chunk_indexes and all(c.message_index_offsets for c in summary.chunk_indexes)
    by_topic = {c.topic: c for c in summary.channels.values()}
    for topic in ('/joint_states', '/ram/twist', '/diagnostics', '/input_speed_cmd',
                  '/parameter_events'):
        assert topic in by_topic, sorted(by_topic)
        channel = by_topic[topic]
        schema = summary.schemas[channel.schema_id]
        assert (channel.message_encoding, schema.encoding, schema.name) == (
            'cdr', 'ros2msg', TYPES[topic])
        assert summary.statistics.channel_message_counts.get(channel.id, 0) == len(
            mcap_decoded.get(topic, []))
        # Schema text exactly as rosbag2 builds it, built here independently.
        assert schema.data.decode() == _expected_definition(TYPES[topic]), topic
        # QoS metadata: YAML, every field rosbag2 writes, the publishers' actual offer.
        profiles = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert profiles and all(set(p) == QOS_FIELDS for p in profiles), profiles
        assert all(p['reliability'] == 'reliable' and p['durability'] == 'volatile'
                   and set(p['deadline']) == {'sec', 'nsec'} for p in profiles), profiles
        assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
        assert run.topics()[topic] == TYPES[topic]
    assert {c.topic for c in connections} == set(by_topic)
    assert all(c.ext.offered_qos_profiles for c in connections)

    ours = {}
    log_times = []
    for topic, schema_name, log_ns, publish_ns, data in run.messages():
        ours.setdefault(topic, []).append((log_ns, publish_ns, data))
        log_times.append(log_ns)
        assert schema_name == TYPES[topic]
        assert 0 <= log_ns - publish_ns < 1_000_000_000  # sent, then received, same clock
    assert log_times == sorted(log_times)
    for topic in ('/joint_states', '/ram/twist', '/diagnostics', '/input_speed_cmd'):
        sent = listener.messages(topic)
        recorded = [m[2] for m in ours.get(topic, [])]
        assert recorded, topic
        if REAL_SIM and topic != '/input_speed_cmd':
            # The real sim publishes at once: the recorder and this listener each match it
            # after their own discovery. From the first message both hold, they must agree.
            common = set(sent)
            skipped = next(i for i, data in enumerate(recorded) if data in common)
            start = sent.index(recorded[skipped])
            recorded = recorded[skipped:]
            sent = sent[start:start + len(recorded)]
            assert 0 in (skipped, start) and recorded == sent, topic
        else:
            assert len(recorded) == len(sent), topic
            assert recorded == sent, topic
        first = len(ours[topic]) - len(recorded)
        assert [m.data for m, _ in mcap_decoded[topic][first:]] == recorded
        assert [d for _, d, _ in rosbags_messages[topic][first:]] == recorded
        message_class = _message_class(TYPES[topic])
        for data, (_, from_mcap), (_, _, from_rosbags) in zip(
                recorded, mcap_decoded[topic][first:], rosbags_messages[topic][first:]):
            expected = _plain(rclpy.serialization.deserialize_message(data, message_class))
            assert _plain(from_mcap) == expected
            assert _plain(from_rosbags) == expected
    assert [_plain(v)['data'] for _, v in mcap_decoded['/input_speed_cmd']] == speeds
    events = [v for _, v in mcap_decoded['/parameter_events']]
    assert any(e.node == '/shaper_sim' and any(
        p.name == 'coupling_offset' and p.value.double_value == 0.012
        for p in e.changed_parameters) for e in events)

    # The run describes itself: geometry exactly as the sim reported it, and all parameters.
    assert [float(run.metadata['qrm_ros.geometry'][n]) for n in GEOMETRY] == geometry
    assert [run.metadata['qrm_ros.geometry'][n] for n in GEOMETRY] == [repr(g) for g in
                                                                       geometry]
    parameters = {k: json.loads(v) for k, v in run.metadata['qrm_ros.parameters'].items()}
    assert [parameters[n] for n in GEOMETRY] == geometry
    assert parameters['coupling_offset'] in (0.01, 0.012) or REAL_SIM

    # rosbags' high-level reader on the rosbag2 folder the file's own rosbag2 record describes.
    from pathlib import Path
    from rosbags.highlevel import AnyReader
    bag = tmp_path / 'bag'
    bag.mkdir()
    metadata = yaml.safe_load(run.metadata['rosbag2']['serialized_metadata'])
    (bag / 'metadata.yaml').write_text(yaml.safe_dump(
        {'rosbag2_bagfile_information': metadata}))
    os.symlink(output, bag / metadata['relative_file_paths'][0])
    with AnyReader([Path(bag)]) as reader:
        counts = {}
        for connection, _, data in reader.messages(connections=reader.connections):
            reader.deserialize(data, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    assert counts == {t: len(v) for t, v in ours.items()}
    assert metadata['message_count'] == sum(counts.values())


def test_sigterm_finishes_the_file(tmp_path, listener):
    output = str(tmp_path / 'run.mcap')
    recorder = Process(_recorder_command(f'output:={output}', 'compression:=lz4'),
                       str(tmp_path), 'recorder')
    publisher = Process(_publisher_command(0, 100.0, 2, forever=True), str(tmp_path),
                        'publisher')
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


def test_sigkill_loses_at_most_one_chunk_duration(tmp_path, listener):
    from sensor_msgs.msg import JointState
    import rclpy.serialization
    chunk_duration = 0.3
    output = str(tmp_path / 'run.mcap')
    recorder = Process(_recorder_command(f'output:={output}',
                                         f'max_chunk_duration:={chunk_duration}'),
                       str(tmp_path), 'recorder')
    publisher = Process(_publisher_command(0, 100.0, 2, forever=True), str(tmp_path),
                        'publisher')
    try:
        wait_for(lambda: len(listener.messages('/joint_states')) >= 150, 15.0,
                 '150 joint states at the listener')
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


def test_existing_output_is_refused(tmp_path):
    output = tmp_path / 'run.mcap'
    output.write_bytes(b'precious')
    recorder = Process(_recorder_command(f'output:={output}'), str(tmp_path), 'recorder')
    recorder.popen.wait(15)
    _check_one_line_error(recorder, 'already exists', str(output))
    assert output.read_bytes() == b'precious'


@pytest.mark.parametrize('parameter, words', [
    ('max_chunk_duration:=0.0', ['max_chunk_duration=0.0', '[0.001, 3600] s']),
    ('sim_wait_timeout:=-1.0', ['sim_wait_timeout=-1.0', '[0, 3600] s']),
    ('compression:=gzip', ["compression='gzip'", 'zstd, lz4, none']),
])
def test_bad_settings_are_refused_naming_the_allowed_values(tmp_path, parameter, words):
    output = tmp_path / 'run.mcap'
    recorder = Process(_recorder_command(f'output:={output}', parameter), str(tmp_path),
                       'recorder')
    recorder.popen.wait(15)
    _check_one_line_error(recorder, *words)
    assert not output.exists()


def test_unwritable_output_gives_one_clear_line(tmp_path):
    blocker = tmp_path / 'not_a_folder'
    blocker.write_text('')
    output = blocker / 'run.mcap'
    recorder = Process(_recorder_command(f'output:={output}'), str(tmp_path), 'recorder')
    recorder.popen.wait(15)
    _check_one_line_error(recorder, 'cannot create output', str(output))
    if os.geteuid() != 0:  # root writes anywhere, so only a normal user can check permissions
        locked = tmp_path / 'locked'
        locked.mkdir(mode=0o500)
        recorder = Process(_recorder_command(f'output:={locked / "run.mcap"}'),
                           str(tmp_path), 'recorder2')
        recorder.popen.wait(15)
        _check_one_line_error(recorder, 'Permission denied')


def test_full_disk_stops_with_one_line_and_keeps_what_was_written(tmp_path):
    limit = 24_000

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
        recorder.popen.wait(30)
    finally:
        publisher.stop()
    _check_one_line_error(recorder, 'cannot write', output, 'errno')
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
