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
"""An MCAP file's parts, each read and checked on its own (the run reader builds on them)."""

import dataclasses

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk
import pytest

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.recording.mcap_structure import (chunk_records, data_section_matches_crc,
                                              describe_error, indexed_message_count,
                                              MAX_CHUNK_BYTES, read_chunk, read_summary,
                                              RunFileError)
from synthetic_run import write_run


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp('structure') / 'run.mcap'
    write_run(path, Geometry.paper(), [0.01], hold=2.0, chunk_size=8 * 1024, data_crc=True)
    return path


def test_a_finished_file_gives_its_summary_and_a_sound_data_section(recorded):
    with open(recorded, 'rb') as handle:
        summary, problem = read_summary(handle)
        assert problem is None and summary is not None and summary.chunk_indexes
        assert data_section_matches_crc(handle)


def test_an_unfinished_file_has_no_summary_and_no_complaint(recorded, tmp_path):
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(recorded.read_bytes()[:-100])
    with open(cut, 'rb') as handle:
        assert read_summary(handle) == (None, None)


def test_each_chunk_holds_what_its_message_indexes_count(recorded):
    with open(recorded, 'rb') as handle:
        summary, _ = read_summary(handle)
        channels = set(summary.channels)
        read = counted = 0
        for index in summary.chunk_indexes:
            read += len(read_chunk(handle, index, channels))
            counted += indexed_message_count(handle, index, channels)
    with open(recorded, 'rb') as handle:
        expected = sum(1 for _ in make_reader(handle).iter_messages())
    assert read == counted == expected > 0


def test_a_chunk_claiming_an_absurd_size_is_refused(recorded):
    with open(recorded, 'rb') as handle:
        summary, _ = read_summary(handle)
        index = summary.chunk_indexes[0]
        handle.seek(index.chunk_start_offset)
        handle.read(9)  # opcode, length
        chunk = Chunk.read(ReadDataStream(handle))
    assert chunk_records(chunk)
    huge = dataclasses.replace(chunk, uncompressed_size=MAX_CHUNK_BYTES + 1)
    with pytest.raises(RunFileError, match='claims'):
        chunk_records(huge)


def test_an_error_is_described_on_one_line():
    assert describe_error(ValueError('bad\nmore')) == 'ValueError: bad'
    assert describe_error(EOFError()) == 'EOFError'
