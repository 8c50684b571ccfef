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
qrm_simulate as a user runs it: its file read by the analysis and by rosbags, its refusals.

The content itself is checked against a live recording in test/node/offline/test_offline_sim.py.
"""

import errno
import json
import math
import os
from pathlib import Path
import subprocess

import pytest
from rosbags.highlevel import AnyReader

from qrm_ros.analysis.measurement import analyse
from qrm_ros.analysis.recorded_run import read_recording
from qrm_ros.cli import exit_codes, qrm_simulate
from qrm_ros.core import kinematics as kin
from damaged_runs import put_together, take_apart
from repo_paths import TEST_DATA
from ros_probe import installed_executable

GOLDEN_RUN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')


def _simulate(*args):
    result = subprocess.run([installed_executable('qrm_simulate'), *map(str, args)],
                            capture_output=True, text=True, timeout=300)
    assert 'Traceback' not in result.stderr
    return result


def test_options_alone_make_a_run_the_analysis_measures(tmp_path):
    path = tmp_path / 'run.mcap'
    result = _simulate('--duration', 8, '-p', 'coupling_offset:=0.01', '-p',
                       'input_speed:=9.0', '--start-time', 100, '--markers', '-o', path)
    assert result.returncode == exit_codes.EXIT_OK, result.stderr
    assert 'wrote' in result.stdout and '800 ticks' in result.stdout
    rows = analyse(read_recording(str(path), {})).rows
    assert len(rows) == 1
    row = rows[0]
    assert row['offset'] == pytest.approx(0.01) and row['input_speed'] == pytest.approx(9.0)
    assert row['time_ratio_measured'] == pytest.approx(
        kin.time_ratio(kin.Geometry.paper(), 0.01), rel=1e-4)
    with AnyReader([Path(path)]) as reader:  # rosbag2's own layout, as rosbags reads it
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts['/joint_states'] == 800 and counts['/linkage_markers'] > 0
        first = next(reader.messages(connections=[
            c for c in reader.connections if c.topic == '/joint_states']))
        message = reader.deserialize(first[2], first[0].msgtype)
    assert message.header.stamp.sec == 100 and message.header.stamp.nanosec == 10_000_000
    assert math.isclose(message.position[4], 0.01)


def _scenario_run(tmp_path, text, *options):
    """Simulate the scenario of this YAML text; return the run file's path."""
    scenario = tmp_path / 'scenario.yaml'
    scenario.write_text(text)
    path = tmp_path / 'run.mcap'
    result = _simulate(scenario, *options, '-o', path)
    assert result.returncode == exit_codes.EXIT_OK, result.stderr
    return path


def test_a_scenario_file_with_an_event(tmp_path):
    path = _scenario_run(tmp_path, 'parameters: {coupling_offset: -0.01, offset_rate_limit: '
                         '0.02}\nduration: 20\n'
                         'events:\n  - {at: 8, set: {coupling_offset: 0.005}}\n')
    offsets = [row['offset'] for row in analyse(read_recording(str(path), {})).rows]
    assert offsets == [pytest.approx(-0.01), pytest.approx(0.005)]


def _load_change_run(tmp_path):
    """A run whose cutting force falls from 400 to 100 N at 6 s (one parameter event)."""
    return _scenario_run(tmp_path, 'parameters: {coupling_offset: 0.005, cutting_force: '
                         '400.0}\nduration: 12\n'
                         'events:\n  - {at: 6, set: {cutting_force: 100.0}}\n', '--markers')


def test_every_message_reads_strictly_and_a_load_change_is_seen(tmp_path):
    path = _load_change_run(tmp_path)
    # rosbags refuses a message with bytes beyond its end (rclpy's serialize_message gave
    # /parameter_events 8 more), so every message of every topic is read here.
    with AnyReader([Path(path)]) as reader:
        read = {}
        for connection, _, data in reader.messages():
            reader.deserialize(data, connection.msgtype)
            read[connection.topic] = read.get(connection.topic, 0) + 1
    assert {'/parameter_events', '/diagnostics', '/linkage_markers'} <= read.keys()
    analysis = analyse(read_recording(str(path), {}))
    assert [segment.drive.loads.cutting_force for segment in analysis.segments] == [400.0, 100.0]
    assert [t['change'] for t in analysis.transitions] == ['cutting_force 400.0 -> 100.0']


def test_an_unreadable_parameter_event_leaves_the_drive_unknown_and_is_said(tmp_path):
    recorded = take_apart(_load_change_run(tmp_path).read_bytes())
    events = next(i for i, c in recorded.channels.items() if c[0] == '/parameter_events')
    for message in recorded.messages:
        if message[0] == events:
            message[4] = message[4][:24]  # cut short: no decoder reads it
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(put_together(recorded))
    result = subprocess.run([installed_executable('qrm_analyze'), str(damaged), '--json',
                             str(tmp_path / 'out.json')], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == exit_codes.EXIT_INCOMPLETE, result.stderr
    assert 'Traceback' not in result.stderr
    said = result.stdout + result.stderr
    assert ('a /parameter_events message (log time' in said
            and 'the masses, loads and drive from the start on are unknown' in said)
    document = json.loads((tmp_path / 'out.json').read_text())
    assert document['complete'] is False
    assert all(row['peak_input_torque_theory'] is None for row in document['segments'])
    assert len(document['segments']) == 1  # no change is made up: one setting throughout


@pytest.mark.parametrize('args, message', [
    (['--duration', 1, '-p', 'coupling_offset:=0.05'],
     'coupling_offset = 0.05 refused: outside the allowed range [-0.0225, 0.0225] m'),
    (['--duration', 1, '-p', 'coupling_offset:=0.0', '-p', 'pivot_distance:=0.01'],
     'pivot_distance'),
    (['--duration', 1, '-p', 'drive:=diesel'], "drive = 'diesel' refused"),
    (['--duration', 1, '-p', 'coupling_offst:=0.0'], 'did you mean coupling_offset?'),
    (['--duration', 1, '-p', 'coupling_offset'], 'write NAME:=VALUE'),
    (['-p', 'coupling_offset:=0.0'], 'no duration'),
    (['--duration', -1], 'duration = -1.0 s'),
    ([GOLDEN_RUN], 'is not a text file (YAML, UTF-8): byte 0 is 0x89'),  # a run, by mistake
])
def test_bad_input_is_refused_in_one_line_and_leaves_no_file(tmp_path, args, message):
    path = tmp_path / 'run.mcap'
    result = _simulate(*args, '-o', path)
    assert result.returncode == exit_codes.EXIT_BAD_INPUT
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert not path.exists()


def test_an_existing_output_is_kept(tmp_path):
    path = tmp_path / 'run.mcap'
    path.write_bytes(b'mine')
    result = _simulate('--duration', 1, '-o', path)
    assert result.returncode == exit_codes.EXIT_BAD_INPUT
    assert 'already exists' in result.stderr and path.read_bytes() == b'mine'


def test_a_progress_bar_when_asked_and_none_off_a_terminal(tmp_path):
    shown = _simulate('--duration', 3, '--progress', 'always', '-o', tmp_path / 'a.mcap')
    assert shown.returncode == exit_codes.EXIT_OK, shown.stderr
    assert 'simulated' in shown.stderr and '3/3 s' in shown.stderr
    # auto: a bar only on a terminal (here stderr is a pipe), whatever the duration.
    quiet = _simulate('--duration', 3, '-o', tmp_path / 'b.mcap')
    assert quiet.returncode == exit_codes.EXIT_OK and 'simulated' not in quiet.stderr


def test_a_write_error_ends_the_run_with_its_reason(tmp_path, monkeypatch, capsys):
    # The disk fills up: a chunk's sync fails (the fourth: chunks close by size offline, so
    # the run is long enough for several). The run file's one-line reason, exit 1, no file.
    syncs = []
    real_fsync = os.fsync

    def filling_fsync(fd):
        syncs.append(fd)
        if len(syncs) > 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)
    monkeypatch.setattr(os, 'fsync', filling_fsync)
    path = tmp_path / 'run.mcap'
    assert qrm_simulate.main(['--duration', '200', '-p', 'publish_rate:=1000.0', '-o', str(path),
                              '--progress', 'never']) == exit_codes.EXIT_FAILURE
    assert len(syncs) == 4  # it ended at the failed sync
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and 'No space left on device' in lines[0], lines
    # The file is gone: the line says so and points to -o, not to a recovery of it.
    assert 'no file was kept' in lines[0] and '(-o PATH)' in lines[0]
    assert '--recover' not in lines[0] and 'output:=' not in lines[0]
    assert not path.exists()
