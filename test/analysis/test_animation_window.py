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
"""qrm_animate's window reading: the frames of the whole-run animation, from the span alone."""

import os

import numpy as np
import pytest

from qrm_ros.analysis import animation
from qrm_ros.analysis import animation_window
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import streamed_run
from qrm_ros.core import kinematics as kin
from synthetic_run import made_up_efforts, write_run
from repo_paths import TEST_DATA


def _whole_run_gif(path, out, start, end, fps, speed):
    recording = recorded_run.read_recording(str(path))
    animation.write_animation(recording, str(out), start, end, fps, speed,
                              efforts=animation.read_efforts(str(path), recording.samples))
    return out.read_bytes()


def _window_gif(path, out, start, end, fps, speed):
    result = streamed_run.analyse_file(str(path), progress_stream=None)
    animation_window.write_window_animation(result, str(out), start, end, fps, speed)
    return out.read_bytes()


@pytest.mark.parametrize('start, end, fps, speed', [
    (0.5, 2.5, 20.0, 2.0),  # a span inside the run, between samples
    (None, None, 5.0, 4.0),  # the whole run
    (1.02, 1.3, 50.0, 0.5),  # the first frame shows a sample before --start
])
def test_window_animation_is_the_whole_run_animation_byte_for_byte(
        tmp_path, run_with_efforts, start, end, fps, speed):
    whole = _whole_run_gif(run_with_efforts, tmp_path / 'whole.gif', start, end, fps, speed)
    window = _window_gif(run_with_efforts, tmp_path / 'window.gif', start, end, fps, speed)
    assert window == whole


def test_window_animation_of_a_run_without_efforts(tmp_path):
    path = os.path.join(TEST_DATA, 'offset_and_speed_change.mcap')
    whole = _whole_run_gif(path, tmp_path / 'whole.gif', 1.0, 3.0, 10.0, 1.0)
    assert _window_gif(path, tmp_path / 'window.gif', 1.0, 3.0, 10.0, 1.0) == whole


def test_only_the_window_is_kept_however_long_the_run(tmp_path):
    windows = []
    for hold in (3.0, 30.0):  # the same start, then a tail ten times as long
        path = tmp_path / f'run_{hold:g}.mcap'
        write_run(path, kin.Geometry.paper(), [0.0], hold=hold, effort=made_up_efforts)
        result = streamed_run.analyse_file(str(path), progress_stream=None)
        windows.append(animation_window.read_window(result, 1.0, 1.5))
        whole = recorded_run.read_recording(str(path)).samples.time
        in_span = np.count_nonzero((whole >= 1.0) & (whole <= 1.5))
        # the samples in the span and the last one before it, nothing else
        assert windows[-1].samples.time.size == in_span + 1 < whole.size / 4
        assert (windows[-1].earliest, windows[-1].latest) == (whole.min(), whole.max())
        assert windows[-1].messages_decoded == whole.size
    short, long = windows
    for name, column in zip(short.samples._fields, short.samples):
        other = getattr(long.samples, name)
        assert (column is None and other is None) or np.array_equal(column, other), name
