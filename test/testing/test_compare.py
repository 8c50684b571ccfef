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
The run comparison of the test kit, on real run files.

The runs are the shipped examples and copies of them written with the package's own writer
(McapRunFile), one value changed by a known amount: a float moved by math.nextafter steps, a
stamp, a log time, a string, a message dropped. Each number asserted is derived here, from the
files and from nextafter, not from the comparison.
"""

import math
import os
import struct
import tracemalloc

import numpy as np
import pytest
from rcl_interfaces.msg import ParameterEvent
from rclpy.serialization import deserialize_message
from rosbags.typesys import get_types_from_msg, get_typestore, Stores

from qrm_ros.recording.bag_reader import open_run, RunFileError
from qrm_ros.recording.mcap_run_file import COMPRESSIONS, McapRunFile
from qrm_ros.recording.typestore import exact_cdr, jazzy_typestore
from qrm_ros.testing import (assert_runs_match, example_names, example_recording, first_difference,
                             LOG_TIME, MESSAGE_COUNT, MESSAGE_TYPE, RunDifference, simulate,
                             ulp_distance)
from repo_paths import REPO_ROOT

STEADY = 'steady_offset'
# ns of log time a chunk of the copies spans.
CHUNK_DURATION = 500_000_000
MIN_SUBNORMAL = math.ulp(0.0)


def _store():
    return jazzy_typestore()


def _write(path, messages, chunk_duration=CHUNK_DURATION, definitions=None):
    """Write (topic, type, log time, data) messages with the package's writer; return path."""
    writer = McapRunFile(str(path), COMPRESSIONS['zstd'], chunk_duration)
    channels = {}
    for topic, type_name, log_time, data in messages:
        if topic not in channels:
            if definitions and type_name in definitions:
                writer.add_schema(type_name, definitions[type_name])
            channels[topic] = writer.add_channel(topic, type_name, '', '')
        writer.add_message(channels[topic], log_time, log_time, data)
    writer.finish()
    return str(path)


def _copy(source, path, edit=None, without=()):
    """
    Copy a run with the package's writer, message by message in log-time order.

    edit(message, index on its topic) returns (log time, data) to write, or None to drop it.
    """
    run = open_run(source)
    writer = McapRunFile(str(path), COMPRESSIONS['zstd'], CHUNK_DURATION)
    channels = {}
    for topic, type_name in run.topics().items():
        if topic not in without:
            writer.add_schema(type_name, run.schema_text(type_name))
            metadata = run.channel_metadata(topic)
            channels[topic] = writer.add_channel(topic, type_name,
                                                 metadata['offered_qos_profiles'],
                                                 metadata['topic_type_hash'])
    counts = {}
    for message in run.messages():
        index = counts[message.topic] = counts.get(message.topic, -1) + 1
        if message.topic in without:
            continue
        written = (message.log_time, message.data) if edit is None else edit(message, index)
        if written is not None:
            writer.add_message(channels[message.topic], written[0], message.publish_time,
                               written[1])
    writer.finish()
    return str(path)


def _changed(topic, index, change):
    """An edit: message `index` of `topic` decoded, changed by change(message), encoded again."""
    def edit(message, at):
        if (message.topic, at) != (topic, index):
            return message.log_time, message.data
        decoded = _store().deserialize_cdr(message.data, message.schema_name)
        change(decoded)
        return message.log_time, bytes(_store().serialize_cdr(decoded, message.schema_name))
    return edit


def _message(path, topic, index):
    """Return the index-th message of a topic in a run file (log time, data, schema name)."""
    return list(open_run(path).messages(topic))[index]


def _decoded(path, topic, index):
    message = _message(path, topic, index)
    return _store().deserialize_cdr(message.data, message.schema_name)


def _stepped(value, steps, toward=math.inf):
    for _ in range(steps):
        value = math.nextafter(value, toward)
    return value


def _set_position(index, value):
    def change(message):
        message.position = message.position.copy()
        message.position[index] = value
    return change


def _set_linear_x(value):
    def change(message):
        message.twist.linear.x = value
    return change


def _float_of_bits(bits):
    return struct.unpack('<d', struct.pack('<Q', bits))[0]


# --- matching runs -------------------------------------------------------------------------

@pytest.mark.parametrize('name', example_names())
def test_a_run_matches_itself_as_a_path_and_as_a_run(name):
    path = example_recording(name)
    assert first_difference(path, path) is None
    assert first_difference(open_run(path), open_run(path)) is None
    assert_runs_match(path, open_run(path))


@pytest.mark.parametrize('name', example_names())
def test_a_copy_of_other_bytes_and_the_same_fields_matches_bit_for_bit(tmp_path, name):
    # 8 bytes past the end of every message, as rclpy's serialize_message leaves: no message
    # is the same bytes, so every one is decoded and compared field by field.
    copy = _copy(example_recording(name), tmp_path / 'copy.mcap',
                 lambda m, i: (m.log_time, m.data + bytes(range(1, 9))))
    assert first_difference(example_recording(name), copy) is None
    assert first_difference(copy, example_recording(name), ulps=4) is None


def _documented_example():
    """The Python block of doc/testing.md's section on comparing two runs."""
    with open(os.path.join(REPO_ROOT, 'doc', 'testing.md')) as stream:
        section = stream.read().split('## Comparing two runs', 1)[1]
    return section.split('```python\n', 1)[1].split('```', 1)[0]


def test_the_documented_example_passes_here(tmp_path):
    # doc/testing.md's test as a user copies it: the simulator on this machine makes the
    # shipped run again (every topic, bit for bit, on a reference machine).
    namespace = {}
    exec(compile(_documented_example(), 'doc/testing.md', 'exec'), namespace)
    namespace['test_this_machine_simulates_the_shipped_run'](tmp_path)


# --- floats --------------------------------------------------------------------------------

def test_a_float_one_ulp_away_fails_bit_for_bit_and_passes_within_one_ulp(tmp_path):
    example = example_recording(STEADY)
    original = float(_decoded(example, '/joint_states', 57).position[3])
    moved = math.nextafter(original, math.inf)
    copy = _copy(example, tmp_path / 'moved.mcap',
                 _changed('/joint_states', 57, _set_position(3, moved)))
    log_time = _message(example, '/joint_states', 57).log_time
    difference = first_difference(example, copy)
    assert difference == RunDifference('/joint_states', 57, log_time, 'position[3]', original,
                                       moved, 1)
    assert str(difference) == (
        f'/joint_states message 57 (log time {log_time} ns): position[3] is {original!r} in '
        f'the first run, {moved!r} in the second (1 ulp apart)')
    assert first_difference(example, copy, ulps=1) is None
    with pytest.raises(AssertionError) as failure:
        assert_runs_match(example, copy)
    assert str(failure.value) == (f'the runs differ (compared bit for bit):\n  first:  '
                                  f'{example}\n  second: {copy}\n  {difference}')
    assert_runs_match(example, copy, 1)


def test_four_ulps_pass_within_four_and_fail_within_three(tmp_path):
    example = example_recording(STEADY)
    original = _decoded(example, '/ram/twist', 200).twist.linear.x
    moved = _stepped(original, 4, -math.inf)
    copy = _copy(example, tmp_path / 'moved.mcap',
                 _changed('/ram/twist', 200, _set_linear_x(moved)))
    difference = first_difference(example, copy, ulps=3)
    assert (difference.field, difference.first, difference.second,
            difference.ulps_apart) == ('twist.linear.x', original, moved, 4)
    assert '(4 ulps apart)' in str(difference)
    assert first_difference(example, copy, ulps=4) is None


def test_ulps_are_counted_across_zero_and_through_the_subnormals(tmp_path):
    # From -2 to +2 smallest subnormals nextafter steps -1, -0.0, +1, +2: four ulps.
    assert ulp_distance(-2 * MIN_SUBNORMAL, 2 * MIN_SUBNORMAL) == 4
    assert _stepped(-2 * MIN_SUBNORMAL, 4) == 2 * MIN_SUBNORMAL
    largest_subnormal = math.nextafter(2.0 ** -1022, 0.0)
    assert ulp_distance(largest_subnormal, 2.0 ** -1022) == 1
    assert ulp_distance(1.0, _stepped(1.0, 1000)) == 1000
    assert ulp_distance(-1.0, _stepped(-1.0, 7, -math.inf)) == 7
    assert ulp_distance(np.float32(1.0), np.nextafter(np.float32(1.0), np.float32(2.0))) == 1
    assert ulp_distance(-0.0, 0.0) == 0
    # A recorded zero (the ram's angular velocity) made two subnormals below zero.
    example = example_recording(STEADY)
    assert _decoded(example, '/ram/twist', 9).twist.angular.z == 0.0
    below = _stepped(0.0, 2, -math.inf)

    def change(message):
        message.twist.angular.z = below
    copy = _copy(example, tmp_path / 'below.mcap', _changed('/ram/twist', 9, change))
    assert first_difference(example, copy, ulps=1).ulps_apart == 2
    assert first_difference(example, copy, ulps=2) is None


def test_minus_zero_differs_from_zero_bit_for_bit_only(tmp_path):
    example = example_recording(STEADY)
    assert math.copysign(1.0, _decoded(example, '/ram/twist', 9).twist.angular.z) == 1.0

    def change(message):
        message.twist.angular.z = -0.0
    copy = _copy(example, tmp_path / 'minus_zero.mcap', _changed('/ram/twist', 9, change))
    difference = first_difference(example, copy)
    assert (difference.field, repr(difference.first), repr(difference.second),
            difference.ulps_apart) == ('twist.angular.z', '0.0', '-0.0', 0)
    assert str(difference).endswith(
        'twist.angular.z is 0.0 in the first run, -0.0 in the second (0 ulps apart, but not '
        'bit for bit: zeros of opposite sign)')
    assert first_difference(example, copy, ulps=1) is None


def test_a_nan_matches_only_a_nan_of_the_same_bits(tmp_path):
    example = example_recording(STEADY)
    quiet = _float_of_bits(0x7ff8000000000000)
    other = _float_of_bits(0x7ff8000000000001)
    first = _copy(example, tmp_path / 'nan.mcap',
                  _changed('/joint_states', 3, _set_position(0, quiet)))
    same = _copy(example, tmp_path / 'same_nan.mcap',
                 _changed('/joint_states', 3, _set_position(0, quiet)))
    assert first_difference(first, same) is None
    differing = _copy(example, tmp_path / 'other_nan.mcap',
                      _changed('/joint_states', 3, _set_position(0, other)))
    difference = first_difference(first, differing, ulps=1000)
    assert (difference.field, difference.ulps_apart) == ('position[0]', None)
    assert str(difference).endswith(
        'position[0] is nan (bits 0x7ff8000000000000) in the first run, nan (bits '
        '0x7ff8000000000001) in the second (NaNs of different bits)')
    against_number = first_difference(example, first, ulps=2 ** 62)
    assert (against_number.field, against_number.ulps_apart) == ('position[0]', None)
    assert str(against_number).endswith('(a NaN is within no ulps of a number)')


def test_an_infinity_equals_only_itself(tmp_path):
    example = example_recording(STEADY)
    largest = _copy(example, tmp_path / 'largest.mcap',
                    _changed('/ram/twist', 5, _set_linear_x(math.nextafter(math.inf, 0.0))))
    infinite = _copy(example, tmp_path / 'infinite.mcap',
                     _changed('/ram/twist', 5, _set_linear_x(math.inf)))
    difference = first_difference(largest, infinite, ulps=10)
    assert (difference.message_index, difference.second, difference.ulps_apart) == (
        5, math.inf, None)
    assert str(difference).endswith('(an infinity equals only itself)')
    assert first_difference(infinite, infinite) is None


@pytest.fixture(scope='module')
def marker_run(tmp_path_factory):
    return simulate({'duration': 1.0, 'parameters': {'coupling_offset': 0.01}},
                    str(tmp_path_factory.mktemp('markers') / 'markers.mcap'), markers=True)


def test_a_float32_field_is_counted_in_float32_ulps(tmp_path, marker_run):
    original = np.float32(_decoded(marker_run, '/linkage_markers', 4).markers[2].color.g)
    moved = np.nextafter(original, np.float32(2.0))

    def change(message):
        message.markers[2].color.g = float(moved)
    copy = _copy(marker_run, tmp_path / 'moved.mcap', _changed('/linkage_markers', 4, change))
    difference = first_difference(marker_run, copy)
    assert (difference.topic, difference.message_index, difference.field) == (
        '/linkage_markers', 4, 'markers[2].color.g')
    assert (difference.first, difference.second, difference.ulps_apart) == (original, moved, 1)
    assert (f'is {str(original)} in the first run, {str(moved)} in the second (1 float32 ulp '
            'apart)') in str(difference)
    assert np.float32(str(original)) == original and np.float32(str(moved)) == moved
    assert first_difference(marker_run, copy, ulps=1) is None


# --- stamps, strings, counts, topics -------------------------------------------------------

def test_a_changed_header_stamp_is_found_unless_stamps_are_left_out(tmp_path):
    example = example_recording(STEADY)
    original = _decoded(example, '/tf', 5).transforms[2].header.stamp.nanosec

    def change(message):
        message.transforms[2].header.stamp.nanosec += 1
    copy = _copy(example, tmp_path / 'stamp.mcap', _changed('/tf', 5, change))
    difference = first_difference(example, copy)
    assert difference[:6] == ('/tf', 5, _message(example, '/tf', 5).log_time,
                              'transforms[2].header.stamp.nanosec', original, original + 1)
    assert first_difference(example, copy, header_stamps=False) is None


def test_a_changed_log_time_is_found_unless_log_times_are_left_out(tmp_path):
    example = example_recording(STEADY)
    log_time = _message(example, '/ram/twist', 3).log_time
    copy = _copy(example, tmp_path / 'late.mcap', lambda m, i: (
        m.log_time + (m.topic == '/ram/twist' and i == 3), m.data))
    difference = first_difference(example, copy)
    assert difference == RunDifference('/ram/twist', 3, log_time, LOG_TIME, log_time,
                                       log_time + 1)
    assert str(difference) == (f'/ram/twist message 3: log time {log_time} ns in the first '
                               f'run, {log_time + 1} ns in the second')
    assert first_difference(example, copy, log_times=False) is None


def test_a_changed_diagnostics_value_names_its_path(tmp_path):
    example = example_recording(STEADY)
    original = _decoded(example, '/diagnostics', 1).status[0].values[5].value
    changed = original[:-1] + ('1' if original[-1] != '1' else '2')

    def change(message):
        message.status[0].values[5].value = changed
    copy = _copy(example, tmp_path / 'value.mcap', _changed('/diagnostics', 1, change))
    difference = first_difference(example, copy)
    assert difference.field == 'status[0].values[5].value'
    assert str(difference).endswith(
        f'status[0].values[5].value is {original!r} in the first run, {changed!r} in the second')


def test_a_long_string_is_shown_around_where_it_differs(tmp_path):
    example = example_recording(STEADY)
    urdf = _decoded(example, '/robot_description', 0).data
    at = urdf.index('<robot name="qrm_shaper">') + len('<robot name="qrm_shape')

    def change(message):
        message.data = urdf[:at] + 'R' + urdf[at + 1:]
    copy = _copy(example, tmp_path / 'urdf.mcap', _changed('/robot_description', 0, change))
    difference = first_difference(example, copy)
    assert difference.field == 'data' and difference.second[at] == 'R'
    text = str(difference)
    assert f"...{urdf[at - 30:at + 30]!r}... ({len(urdf)} characters, the first different at " \
           f'{at})' in text
    assert len(text) < 400


def test_a_changed_parameter_event_names_its_path(tmp_path):
    example = example_recording('offset_step')
    event = deserialize_message(_message(example, '/parameter_events', 0).data, ParameterEvent)
    original = event.changed_parameters[0].value.double_value
    moved = math.nextafter(original, math.inf)
    copy = _copy(example, tmp_path / 'event.mcap', lambda m, i: (
        m.log_time, exact_cdr(event, m.schema_name) if m.topic == '/parameter_events'
        else m.data))
    assert first_difference(example, copy) is None  # the event's bytes, not its fields
    event.changed_parameters[0].value.double_value = moved
    moved_copy = _copy(example, tmp_path / 'moved_event.mcap', lambda m, i: (
        m.log_time, exact_cdr(event, m.schema_name) if m.topic == '/parameter_events'
        else m.data))
    difference = first_difference(example, moved_copy)
    assert difference[:7] == ('/parameter_events', 0,
                              _message(example, '/parameter_events', 0).log_time,
                              'changed_parameters[0].value.double_value', original, moved, 1)


def test_a_dropped_message_is_found_where_the_runs_part(tmp_path):
    example = example_recording(STEADY)
    copy = _copy(example, tmp_path / 'dropped.mcap', lambda m, i: (
        None if m.topic == '/joint_states' and i == 100 else (m.log_time, m.data)))
    times = [m.log_time for m in open_run(example).messages('/joint_states')]
    difference = first_difference(example, copy)
    assert difference == RunDifference('/joint_states', 100, times[100], LOG_TIME, times[100],
                                       times[101])
    stamps = [_decoded(example, '/joint_states', i).header.stamp for i in (100, 101)]
    without_log_times = first_difference(example, copy, log_times=False)
    assert without_log_times[:3] == ('/joint_states', 100, times[100])
    assert stamps[0].sec == stamps[1].sec and stamps[0].nanosec != stamps[1].nanosec
    assert without_log_times[3:6] == ('header.stamp.nanosec', stamps[0].nanosec,
                                      stamps[1].nanosec)
    neither = first_difference(example, copy, log_times=False, header_stamps=False)
    assert neither[:4] == ('/joint_states', 100, times[100], 'position[0]')


def test_a_different_message_count_says_both_counts(tmp_path):
    example = example_recording(STEADY)
    times = [m.log_time for m in open_run(example).messages('/tf')]
    copy = _copy(example, tmp_path / 'short.mcap', lambda m, i: (
        None if m.topic == '/tf' and i == len(times) - 1 else (m.log_time, m.data)))
    last = len(times) - 1
    assert first_difference(example, copy) == RunDifference(
        '/tf', last, times[last], MESSAGE_COUNT, len(times), last)
    difference = first_difference(copy, example)
    assert difference == RunDifference('/tf', last, times[last], MESSAGE_COUNT, last,
                                       len(times))
    assert str(difference) == (f'/tf has {last} messages in the first run, {len(times)} in '
                               f'the second: /tf message {last} (log time {times[last]} ns) '
                               'is in the second run only')


def test_a_missing_topic_is_found_unless_the_topics_left_out_it(tmp_path):
    example = example_recording(STEADY)
    copy = _copy(example, tmp_path / 'no_twist.mcap', without=('/ram/twist',))
    difference = first_difference(example, copy)
    assert difference == RunDifference('/ram/twist', None, None, MESSAGE_TYPE,
                                       'geometry_msgs/msg/TwistStamped', None)
    assert str(difference) == ('/ram/twist (geometry_msgs/msg/TwistStamped) is in the first '
                               'run only')
    assert first_difference(example, copy, topics=['joint_states', '/tf']) is None
    assert first_difference(example, copy, topics='joint_states') is None
    with pytest.raises(ValueError, match='/nothing: in neither run'):
        first_difference(example, copy, topics=['nothing'])


def test_a_topic_of_another_type_is_found(tmp_path):
    text = _write(tmp_path / 'text.mcap', [('/x', 'std_msgs/msg/String', 1, bytes(
        _store().serialize_cdr(_store().types['std_msgs/msg/String'](data='1'),
                               'std_msgs/msg/String')))])
    number = _write(tmp_path / 'number.mcap', [('/x', 'std_msgs/msg/Float64', 1, bytes(
        _store().serialize_cdr(_store().types['std_msgs/msg/Float64'](data=1.0),
                               'std_msgs/msg/Float64')))])
    assert str(first_difference(text, number)) == (
        '/x is of type std_msgs/msg/String in the first run, std_msgs/msg/Float64 in the second')


# --- bytes that are no field ---------------------------------------------------------------

def _joint_state(position):
    store = _store()
    types = store.types
    message = types['sensor_msgs/msg/JointState'](
        header=types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=1, nanosec=2), frame_id='b'),
        name=['a'], position=np.array([position]), velocity=np.array([]),
        effort=np.array([]))
    return bytes(store.serialize_cdr(message, 'sensor_msgs/msg/JointState'))


def test_padding_and_bytes_past_the_end_are_no_field(tmp_path):
    # CDR by hand, offsets from the start of the data (after 4 bytes of encapsulation):
    # 0 sec, 4 nanosec, 8 length 2, 12 'b\0', 14-15 padding, 16 one name, 20 length 2,
    # 24 'a\0', 26-27 padding, 28 one position, 32 the double, 40 no velocity, 44 no effort.
    data = _joint_state(0.5)
    assert len(data) == 4 + 48 and data[4 + 32:4 + 40] == struct.pack('<d', 0.5)
    padding = [4 + 14, 4 + 15, 4 + 26, 4 + 27]
    assert all(data[i] == 0 for i in padding)
    garbled = bytearray(data)
    for i in padding:
        garbled[i] = 0xab
    longer = data + b'\x00\x00\x00\x00\x20\x01\x00\x00'  # as rclpy's estimated size leaves
    clean = _write(tmp_path / 'clean.mcap', [('/joint_states', 'sensor_msgs/msg/JointState',
                                              1, data)])
    for name, other in [('garbled', bytes(garbled)), ('longer', longer)]:
        assert first_difference(clean, _write(tmp_path / f'{name}.mcap', [
            ('/joint_states', 'sensor_msgs/msg/JointState', 1, other)])) is None
    moved = _write(tmp_path / 'moved.mcap', [('/joint_states', 'sensor_msgs/msg/JointState',
                                              1, _joint_state(math.nextafter(0.5, 1.0)))])
    assert first_difference(clean, moved)[3:] == ('position[0]', 0.5,
                                                  math.nextafter(0.5, 1.0), 1)


def test_a_type_of_the_runs_own_is_decoded_from_its_recorded_definition(tmp_path):
    type_name = 'qrm_test_msgs/msg/Reading'
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg('std_msgs/Header header\nfloat64[] values\nstring label\n',
                                      type_name))
    definition = store.generate_msgdef(type_name, ros_version=2)[0]
    Reading = store.types[type_name]
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']

    def run(path, last):
        return _write(path, [('/reading', type_name, i, bytes(store.serialize_cdr(
            Reading(Header(Time(0, i), 'x'), np.array([0.25, last if i == 2 else 1.0]), 'r'),
            type_name))) for i in range(3)], definitions={type_name: definition})
    first = run(tmp_path / 'first.mcap', 1.0)
    assert first_difference(first, first) is None
    difference = first_difference(first, run(tmp_path / 'second.mcap', -1.0))
    assert difference[:6] == ('/reading', 2, 2, 'values[1]', 1.0, -1.0)


# --- bad input, memory ---------------------------------------------------------------------

def test_a_missing_or_unreadable_file_is_a_clear_error(tmp_path):
    example = example_recording(STEADY)
    with pytest.raises(RunFileError, match='does not exist'):
        first_difference(example, tmp_path / 'missing.mcap')
    (tmp_path / 'notes.txt').write_text('not a run')
    with pytest.raises(RunFileError, match='is not an MCAP file'):
        assert_runs_match(tmp_path / 'notes.txt', example)
    with pytest.raises(RunFileError, match='is a folder'):
        first_difference(tmp_path, example)
    for ulps in (-1, 1.5, True):
        with pytest.raises(ValueError, match='must be a whole number'):
            first_difference(example, example, ulps)


def _peak_memory(work):
    """Return the most memory (bytes) Python held at once while work() ran."""
    tracemalloc.start()
    try:
        work()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_long_run_is_compared_in_the_memory_of_a_few_chunks(tmp_path):
    # 20000 joint states at 1 kHz, chunks of 0.1 s (100 messages); every tenth message of
    # the second run holds 8 bytes past its end, so it is decoded and compared by fields.
    count = 20000
    datas = [_joint_state(i / count) for i in range(count)]
    first = open_run(_write(tmp_path / 'first.mcap', [
        ('/joint_states', 'sensor_msgs/msg/JointState', i * 1_000_000, data)
        for i, data in enumerate(datas)], chunk_duration=100_000_000))
    second = open_run(_write(tmp_path / 'second.mcap', [
        ('/joint_states', 'sensor_msgs/msg/JointState', i * 1_000_000,
         data + bytes(8) if i % 10 == 0 else data)
        for i, data in enumerate(datas)], chunk_duration=100_000_000))
    assert first_difference(first, second) is None  # the decoder's code made once
    loaded = _peak_memory(lambda: list(first.messages()))
    compared = _peak_memory(lambda: first_difference(first, second))
    assert compared < loaded / 10
