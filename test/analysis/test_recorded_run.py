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
"""Reading a run file: the progress bar, parallel and fast decoding give what rosbags gives."""

import io
import os

import numpy as np
import pytest

from qrm_ros.analysis import joint_state_decoding
from qrm_ros.analysis import recorded_run
from qrm_ros.recording import bag_reader
from qrm_ros.core import kinematics as kin
from synthetic_run import write_run
from repo_paths import TEST_DATA

PAPER = kin.Geometry.paper()


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_bar_only_on_a_terminal_and_long_files(tmp_path, monkeypatch):
    path = tmp_path / 'run.mcap'
    count = write_run(path, PAPER, [0.0], hold=60.0)
    terminal, pipe = Terminal(), io.StringIO()
    recorded_run.read_recording(str(path), progress_stream=pipe)
    recorded_run.read_recording(str(path), progress_stream=terminal)
    assert pipe.getvalue() == '' and terminal.getvalue() == ''  # too short for a bar
    monkeypatch.setattr(recorded_run, 'PROGRESS_MIN_MESSAGES', 100)
    recorded_run.read_recording(str(path), progress_stream=terminal)
    bar = terminal.getvalue()
    assert bar.startswith('\rreading joint states [') and bar.endswith('] 100%\n')
    assert bar.count('\r') == count // 5000 + 1


def test_parallel_decoding_gives_the_same_samples_as_serial(tmp_path, monkeypatch):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [-0.01, 0.01], hold=15.0, chunk_size=16 * 1024)
    serial = recorded_run.read_recording(str(path)).samples
    monkeypatch.setattr(recorded_run, 'PARALLEL_MIN_MESSAGES', 0)
    monkeypatch.setattr(recorded_run, 'usable_cores', lambda: 3)
    parts = bag_reader.open_run(str(path)).parts(3)
    assert len(parts) == 3  # really split
    parallel = recorded_run.read_recording(str(path)).samples
    for name, values in serial._asdict().items():
        np.testing.assert_array_equal(getattr(parallel, name), values, err_msg=name)


@pytest.mark.parametrize('log', sorted(os.listdir(TEST_DATA)))
def test_fast_decoding_gives_what_rosbags_gives_message_by_message(log, monkeypatch):
    if not log.endswith('.mcap'):
        return
    path = os.path.join(TEST_DATA, log)
    fast = recorded_run.read_recording(path)
    monkeypatch.setattr(joint_state_decoding, 'FAST_DECODING', False)
    slow = recorded_run.read_recording(path)
    assert fast.messages_read == slow.messages_read > 0
    for name, values in slow.samples._asdict().items():
        np.testing.assert_array_equal(getattr(fast.samples, name), values, err_msg=name)
