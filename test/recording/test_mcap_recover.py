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
``mcap_recorder --recover`` on damage only decompression finds (recording.mcap_recover).

A file written without CRCs (the format allows it) with bytes overwritten inside a
zstd-compressed chunk: the chunk is skipped and named, the rest kept, the losses kept in the
recovered file's metadata and said again by qrm_analyze (exit 3); output all or nothing.
In-process (recover_command is what the command runs), so fast.
"""

import io
import os

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
import pytest
from qrm_ros.cli import qrm_analyze
from qrm_ros.cli.exit_codes import EXIT_INCOMPLETE
from qrm_ros.recording.bag_reader import open_run
from qrm_ros.recording.mcap_recover import (RECOVERY_METADATA, recover, recover_command,
                                            recovered_losses)

from repo_paths import TEST_DATA


def _run_without_crcs(path, chunks=5, per_chunk=20):
    """Write a small zstd file without any CRC; return each chunk's end offset."""
    with open(path, 'wb') as handle:
        writer = Writer(handle, chunk_size=1 << 40, compression=CompressionType.ZSTD,
                        enable_crcs=False, enable_data_crcs=False)
        writer.start('ros2', 'test')
        schema = writer.register_schema('std_msgs/msg/Float64', 'ros2msg', b'float64 data\n')
        channel = writer.register_channel('/x', 'cdr', schema)
        ends = []
        for index in range(chunks * per_chunk):
            writer.add_message(channel, 1000 + index, index.to_bytes(4, 'little') * 8,
                               500 + index)
            if index % per_chunk == per_chunk - 1:
                writer.flush()
                ends.append(handle.tell())
        writer.finish()
    return ends


def _usage_error(message):
    raise AssertionError(f'usage error: {message}')


def test_a_chunk_only_decompression_finds_damaged_is_skipped_and_named(tmp_path):
    path = tmp_path / 'plain.mcap'
    ends = _run_without_crcs(path)
    data = bytearray(path.read_bytes())
    inside = ends[0] + 128  # the second chunk's compressed body
    data[inside:inside + 8] = b'\xff' * 8
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(bytes(data))
    fixed = tmp_path / 'fixed.mcap'
    out, err = io.StringIO(), io.StringIO()
    assert recover_command(str(damaged), str(fixed), _usage_error, out, err) == 0
    assert 'Traceback' not in err.getvalue()
    warnings = [line for line in err.getvalue().splitlines() if 'warning:' in line]
    assert len(warnings) == 1 and 'lost a damaged chunk holding log time 1020 to 1039 ns' in (
        warnings[0])
    assert 'recovered 80 messages' in out.getvalue()
    with open(fixed, 'rb') as handle:
        times = [message.log_time for _, _, message in make_reader(handle).iter_messages()]
    assert times == [1000 + i for i in list(range(20)) + list(range(40, 100))]
    # The loss travels with the file, and a second recovery keeps it.
    kept = open_run(str(fixed)).metadata
    assert recovered_losses(kept) == [warnings[0].split('warning: ', 1)[1]]
    again = tmp_path / 'again.mcap'
    assert recover_command(str(fixed), str(again), _usage_error, io.StringIO(),
                           io.StringIO()) == 0
    assert open_run(str(again)).metadata[RECOVERY_METADATA] == kept[RECOVERY_METADATA]


def test_a_chunk_length_too_large_to_hold_ends_the_reading_without_a_traceback(tmp_path):
    path = tmp_path / 'plain.mcap'
    ends = _run_without_crcs(path)
    data = bytearray(path.read_bytes())
    data[ends[0] + 48:ends[0] + 56] = b'\xff' * 8  # the second chunk's records length
    damaged, fixed = tmp_path / 'damaged.mcap', tmp_path / 'fixed.mcap'
    damaged.write_bytes(bytes(data))
    out, err = io.StringIO(), io.StringIO()
    assert recover_command(str(damaged), str(fixed), _usage_error, out, err) == 0
    assert 'recovered 20 messages' in out.getvalue()
    assert 'are not readable (OverflowError' in err.getvalue()


def test_a_recovered_golden_log_is_reported_incomplete_again_by_the_analysis(tmp_path,
                                                                             capsys):
    # The golden log's chunks carry CRCs; overwritten inside a compressed body, the damage
    # is found as decompression fails (a ZstdError, once a traceback and a partial file).
    data = bytearray(open(os.path.join(TEST_DATA, 'offset_and_speed_change.mcap'),
                          'rb').read())
    at = int(len(data) * 0.4)
    data[at:at + 8] = b'\xff' * 8
    damaged, fixed = tmp_path / 'damaged.mcap', tmp_path / 'fixed.mcap'
    damaged.write_bytes(bytes(data))
    err = io.StringIO()
    assert recover_command(str(damaged), str(fixed), _usage_error, io.StringIO(), err) == 0
    lost = [line.split('warning: ', 1)[1] for line in err.getvalue().splitlines()]
    assert lost and lost[0].startswith('lost a damaged chunk holding log time')
    capsys.readouterr()
    assert qrm_analyze.main([str(fixed)]) == EXIT_INCOMPLETE
    said = capsys.readouterr().err
    assert 'recovered with losses by mcap_recorder --recover: ' + lost[0] in said


def test_a_recovery_that_fails_midway_leaves_no_file(tmp_path, monkeypatch):
    path = tmp_path / 'plain.mcap'
    _run_without_crcs(path)
    fixed = tmp_path / 'fixed.mcap'

    def full_disk(*arguments):
        raise OSError(28, 'No space left on device')
    from qrm_ros.recording import mcap_run_file
    monkeypatch.setattr(mcap_run_file.McapRunFile, 'finish', full_disk)
    with pytest.raises(OSError):
        recover(str(path), str(fixed))
    assert not fixed.exists()


def test_the_command_says_it_on_the_streams_of_the_moment(tmp_path, capsys):
    """Its defaults are the process's streams when it runs, not those of the import."""
    path = tmp_path / 'plain.mcap'
    _run_without_crcs(path)
    assert recover_command(str(path), str(tmp_path / 'fixed.mcap'), _usage_error) == 0
    assert 'recovered' in capsys.readouterr().out
