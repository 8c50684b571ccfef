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
The streamed analysis against the whole-run one: the same results, bit for bit.

``streamed_run.analyse_file`` must give what ``analyse(read_recording(path))`` gives (the
JSON document, the table, what was lost, the refusals) on the golden logs, synthetic runs
with gaps and clock jumps, and damaged files; with the decoder's blocks made tiny, so every
carry across blocks (repeated stamps, gaps, segments, transitions) is exercised too. Its
figures draw the same points, from the excerpts it keeps.
"""

import glob
import io
import json
import os
import sys

import numpy as np
import pytest

from qrm_ros.analysis import figures, joint_state_decoding, measurement, recorded_run, report
from qrm_ros.analysis import streamed_run
from qrm_ros.analysis.recorded_drive import drive_values
from damaged_runs import cases
from repo_paths import TEST_DATA
from synthetic_run import PAPER, write_run

GOLDEN = sorted(glob.glob(os.path.join(TEST_DATA, '*.mcap')))


def _both(path):
    """Return (whole-run analysis, streamed analysis), or the two refusals' texts."""
    try:
        whole = measurement.analyse(recorded_run.read_recording(str(path)))
    except recorded_run.AnalysisError as error:
        with pytest.raises(recorded_run.AnalysisError) as streamed_error:
            streamed_run.analyse_file(str(path))
        return str(error), str(streamed_error.value)
    return whole, streamed_run.analyse_file(str(path))


def _assert_same(path):
    whole, streamed = _both(path)
    if isinstance(whole, str):
        assert whole == streamed
        return
    assert json.dumps(report.to_document(whole)) == json.dumps(report.to_document(streamed))
    assert report.format_table(whole) == report.format_table(streamed)
    assert report.incompleteness(whole.recording) == report.incompleteness(streamed.recording)
    assert [(s.offset, s.input_speed, drive_values(s.drive)) for s in whole.segments] == [
        (s.offset, s.input_speed, drive_values(s.drive)) for s in streamed.segments]


@pytest.fixture(params=[joint_state_decoding.PROGRESS_STEP, 7], ids=['blocks', 'tiny-blocks'])
def block_size(request, monkeypatch):
    monkeypatch.setattr(joint_state_decoding, 'PROGRESS_STEP', request.param)
    return request.param


@pytest.mark.parametrize('path', GOLDEN, ids=os.path.basename)
def test_golden_logs_give_the_same_results(path, block_size):
    _assert_same(path)


def _with_gaps(tmp_path):
    """A synthetic run with a pause, a clock jump back and a repeated message."""
    source = tmp_path / 'source.mcap'
    write_run(source, PAPER, [-0.01, 0.005, 0.01], hold=3.0)
    from mcap.reader import make_reader
    from mcap.writer import Writer
    target = tmp_path / 'gaps.mcap'
    with open(source, 'rb') as handle, open(target, 'wb') as out:
        reader = make_reader(handle)
        writer = Writer(out)
        writer.start('ros2', 'test')
        summary = reader.get_summary()
        for schema in summary.schemas.values():
            writer.register_schema(schema.name, schema.encoding, schema.data)
        for channel in summary.channels.values():
            writer.register_channel(channel.topic, channel.message_encoding, channel.schema_id,
                                    channel.metadata)
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)
        first_data = b''
        for index, (_, channel, message) in enumerate(reader.iter_messages()):
            if 200 <= index < 260:  # a pause: these are never written
                continue
            copies = 2 if index in (500, 501) else 1  # exact repeats
            for _ in range(copies):
                writer.add_message(channel.id, message.log_time, message.data,
                                   message.publish_time)
            if index == 900:  # a clock jump back: an earlier message again, later on
                writer.add_message(channel.id, message.log_time + 1, first_data,
                                   message.publish_time)
            if index == 0:
                first_data = message.data
        writer.finish()
    return target


def test_a_run_with_gaps_repeats_and_a_clock_jump_gives_the_same(tmp_path, block_size):
    path = _with_gaps(tmp_path)
    whole, _ = _both(path)
    assert any(t['kind'] == 'gap' for t in whole.transitions)
    assert whole.recording.repeated_stamps or whole.recording.losses
    _assert_same(path)


@pytest.mark.parametrize('number', range(0, 300, 15))
def test_damaged_runs_give_the_same_results(number, tmp_path, monkeypatch):
    logs = {os.path.basename(p)[:-5]: open(p, 'rb').read() for p in GOLDEN}
    monkeypatch.setattr(joint_state_decoding, 'PROGRESS_STEP', 7 if number % 2 else 5000)
    path = tmp_path / 'run.mcap'
    path.write_bytes(_fuzz_cases(logs)[number].data)
    _assert_same(path)


_CASES = []


def _fuzz_cases(logs):
    if not _CASES:
        _CASES.extend(cases(logs, 300, 20261122))
    return _CASES


def _drawn(figure):
    return [(line.get_gid(), np.asarray(line.get_xydata()).tolist())
            for axes in figure.axes for line in axes.get_lines()]


def test_the_figures_draw_the_same_points(block_size):
    path = os.path.join(TEST_DATA, 'motor_cutting_load.mcap')
    whole, streamed = _both(path)
    for name, build in figures.FIGURES.items():
        drawn_whole, drawn_streamed = build(whole), build(streamed)
        try:
            assert _drawn(drawn_whole) == _drawn(drawn_streamed), name
        finally:
            figures.plt.close(drawn_whole)
            figures.plt.close(drawn_streamed)


def test_the_streamed_run_keeps_only_excerpts():
    path = os.path.join(TEST_DATA, 'offset_and_speed_change.mcap')
    whole, streamed = _both(path)
    assert streamed.recording.sample_count == whole.recording.samples.time.size
    assert streamed.recording.samples.time.size < whole.recording.samples.time.size / 2


def test_the_analysis_binds_no_stream_when_imported(monkeypatch):
    """A library call touches no stream it was not given (none kept from import time)."""
    closed = io.StringIO()
    closed.close()
    monkeypatch.setattr(sys, 'stderr', closed)
    for read in (streamed_run.analyse_file,
                 lambda path: measurement.analyse(recorded_run.read_recording(path))):
        assert read(GOLDEN[0]).rows
