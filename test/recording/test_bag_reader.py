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
The run reader on its own: its record type, its state, and damage it must not pass over.

Counts are checked against rosbags' own MCAP reader (an independent implementation) on the
undamaged file.
"""

from pathlib import Path

from mcap.reader import make_reader
import pytest

from qrm_ros.core import kinematics as kin
from qrm_ros.recording.bag_reader import Loss, MessageTuple, open_run, RunFileError
from synthetic_run import write_run
from repo_paths import TEST_DATA

PAPER = kin.Geometry.paper()


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp('reader') / 'run.mcap'
    write_run(path, PAPER, [0.0, 0.01], hold=3.0, chunk_size=8 * 1024)
    return path


def _independent(path):
    from rosbags.highlevel import AnyReader
    with AnyReader([Path(path)]) as reader:
        return [(log_time, bytes(data)) for _, log_time, data in
                reader.messages(connections=reader.connections)]


def _chunks(path):
    with open(path, 'rb') as handle:
        return sorted(make_reader(handle).get_summary().chunk_indexes,
                      key=lambda c: c.chunk_start_offset)


def test_messages_are_named_tuples_that_still_unpack(recorded):
    first = next(open_run(recorded).messages())
    assert isinstance(first, MessageTuple) and isinstance(first, tuple)
    topic, schema, log_time, publish_time, data = first
    assert (first.topic, first.schema_name, first.log_time, first.publish_time, first.data) == (
        topic, schema, log_time, publish_time, data)
    assert topic == '/joint_states' and schema == 'sensor_msgs/msg/JointState'
    assert log_time - publish_time == 250_000  # as synthetic_run wrote them


def test_every_attribute_is_set_when_opened_and_reading_adds_none(recorded, tmp_path):
    unfinished = tmp_path / 'unfinished.mcap'
    unfinished.write_bytes(recorded.read_bytes()[:_chunks(recorded)[3].chunk_start_offset])
    indexed, streamed = open_run(recorded), open_run(unfinished)
    assert vars(indexed).keys() == vars(streamed).keys()
    for run in (indexed, streamed):
        before = dict(vars(run))
        assert sum(1 for _ in run.messages()) > 0
        assert vars(run) == before
    assert not indexed.truncated and indexed.data_complete and indexed.counted
    assert streamed.truncated and not streamed.data_complete and not streamed.counted


def test_every_path_reads_what_an_independent_reader_reads(recorded):
    expected = _independent(recorded)
    run = open_run(recorded)
    assert [(m.log_time, m.data) for m in run.messages()] == expected  # log-time order
    assert [(m.log_time, m.data) for m in run.messages(log_time_order=False)] == expected
    parts = run.parts(3)
    assert len(parts) == 3
    in_parts = [(m.log_time, m.data) for part in parts
                for m in run.messages(log_time_order=False, part=part)]
    assert in_parts == expected  # each message in exactly one part
    middle = expected[len(expected) // 2][0]
    assert [(m.log_time, m.data) for m in run.messages(starting_at=middle)] == [
        e for e in expected if e[0] >= middle]


def test_a_damaged_chunk_raises_or_is_reported_with_its_span_and_count(recorded, tmp_path):
    index = _chunks(recorded)[2]
    data = bytearray(recorded.read_bytes())
    data[index.chunk_start_offset + 70] ^= 0x10  # one bit inside the compressed records
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(bytes(data))
    run = open_run(damaged)
    assert not run.truncated  # the damage is in a chunk: found when read
    with pytest.raises(RunFileError, match=f'damaged chunk at byte {index.chunk_start_offset}'):
        list(run.messages())
    losses = []
    read = [(m.log_time, m.data) for m in run.messages(on_loss=losses.append)]
    expected = _independent(recorded)
    held = [e for e in expected
            if index.message_start_time <= e[0] <= index.message_end_time]
    assert read == [e for e in expected if e not in held]
    (loss,) = losses
    assert isinstance(loss, Loss)
    assert (loss.start_time, loss.end_time, loss.messages) == (
        index.message_start_time, index.message_end_time, len(held))


def test_a_damaged_summary_is_not_trusted_and_the_data_section_is_read(recorded, tmp_path):
    data = bytearray(recorded.read_bytes())
    data[-60] ^= 0x01  # inside the summary section (statistics, indexes): CRC-covered
    damaged = tmp_path / 'summary.mcap'
    damaged.write_bytes(bytes(data))
    run = open_run(damaged)
    assert run.truncated and 'summary section fails its CRC' in run.problem
    assert run.data_complete
    assert [(m.log_time, m.data) for m in run.messages()] == _independent(recorded)


@pytest.mark.parametrize('log', ['offset_and_speed_change', 'steady_negative_offset',
                                 'steady_positive_offset'])
def test_the_golden_logs_read_as_rosbags_reads_them(log):
    path = Path(TEST_DATA) / f'{log}.mcap'
    run = open_run(path)
    assert [(m.log_time, m.data) for m in run.messages()] == _independent(path)
    with open(path, 'rb') as handle:  # the mcap library's own reader, in file order
        expected = [(m.log_time, m.data) for _, _, m in
                    make_reader(handle).iter_messages(log_time_order=False)]
    assert [(m.log_time, m.data) for m in run.messages(log_time_order=False)] == expected


def test_damage_outside_the_chunks_is_caught_by_the_data_section_crc(tmp_path):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.01], hold=2.0, data_crc=True)
    assert not open_run(path).truncated  # the check passes on a sound file
    data = path.read_bytes()
    value = data.index(b"'0.0505'" if b"'0.0505'" in data else b'0.0505')
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(data[:value] + b'0.0605' + data[value + 6:])  # still a fine number
    run = open_run(damaged)
    assert run.truncated and 'data section fails its CRC' in run.problem
    assert run.metadata['qrm_ros.geometry']['crank_radius'] == '0.0605'  # read, not trusted
    assert sum(1 for _ in run.messages()) == 200
