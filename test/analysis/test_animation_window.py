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
from qrm_ros.analysis import measurement
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


def _whole_run_tour(path, out):
    result = measurement.analyse(recorded_run.read_recording(str(path)))
    assert animation.write_offset_tour(result, str(out)) == str(out)
    return out.read_bytes()


def _window_tour(path, out, trace_bins):
    result = streamed_run.analyse_file(str(path), progress_stream=None)
    assert animation_window.write_window_tour(result, str(out), trace_bins=trace_bins) == str(out)
    return out.read_bytes()


@pytest.fixture(scope='module')
def five_offsets_run(tmp_path_factory):
    """A run at five offsets (the tour shows four), its joint states carrying efforts."""
    path = tmp_path_factory.mktemp('tour') / 'five_offsets.mcap'
    write_run(path, kin.Geometry.paper(), [-0.01, -0.005, 0.0, 0.005, 0.01], hold=1.5,
              effort=made_up_efforts)
    return path


@pytest.mark.parametrize('name', ['five_offsets', 'efforts', 'no_efforts'])
def test_streamed_offset_tour_is_the_whole_run_tour_byte_for_byte(
        tmp_path, request, name):
    path = {'five_offsets': lambda: request.getfixturevalue('five_offsets_run'),
            'efforts': lambda: request.getfixturevalue('run_with_efforts'),
            'no_efforts': lambda: os.path.join(TEST_DATA, 'offset_and_speed_change.mcap'),
            }[name]()
    whole = _whole_run_tour(path, tmp_path / 'whole.gif')
    # a trace not thinned (a bin per sample): the same picture, frame for frame
    assert _window_tour(path, tmp_path / 'window.gif', trace_bins=10 ** 9) == whole


def test_the_thinned_trace_keeps_each_bins_extremes_however_the_blocks_fall():
    generator = np.random.default_rng(7)
    size, bin_size = 5003, 37
    time = np.cumsum(generator.uniform(0.0, 0.02, size)) - 3.0
    time[2000:2100] -= 1.0  # a clock jump back: the least time is not the first
    velocity, torque = generator.normal(size=size), generator.normal(size=size)
    torque[100:300] = np.nan  # messages without efforts
    samples = recorded_run.Samples(time, *[np.zeros(size)] * 5, velocity, np.zeros(size),
                                   np.zeros(size), torque)
    expected = []
    for start in range(0, size, bin_size):
        chosen = set()
        for column in (time, velocity, torque):
            part = column[start:start + bin_size]
            if np.isfinite(part).any():
                chosen |= {start + int(np.nanargmin(part)), start + int(np.nanargmax(part))}
        expected += sorted(chosen)
    for cuts in ([], [1, 36, 37, 38, 2500, 5000], sorted(generator.choice(size, 60, False))):
        envelope = animation_window.TraceEnvelope(bin_size)
        for low, high in zip([0, *cuts], [*cuts, size]):
            envelope.add(low, recorded_run.Samples._make(
                None if column is None else column[low:high] for column in samples))
        drawn_time, drawn_velocity, drawn_torque = envelope.trace()
        np.testing.assert_array_equal(drawn_time, time[expected])
        np.testing.assert_array_equal(drawn_velocity, velocity[expected])
        np.testing.assert_array_equal(drawn_torque, torque[expected])


def test_the_tour_reads_the_same_few_samples_however_long_the_run(tmp_path):
    tours = []
    for hold in (3.0, 30.0):  # the same offsets, held ten times as long
        path = tmp_path / f'run_{hold:g}.mcap'
        write_run(path, kin.Geometry.paper(), [0.0, 0.01], hold=hold, effort=made_up_efforts)
        result = streamed_run.analyse_file(str(path), progress_stream=None)
        tours.append(animation_window.read_tour(result, trace_bins=20))
        whole = recorded_run.read_recording(str(path)).samples
        time, velocity, torque = tours[-1].trace
        assert time.size <= 6 * 20 < whole.time.size / 5
        # the time panel spans the whole run and the whole swing of each trace
        for drawn, recorded in ((time, whole.time), (velocity, whole.ram_velocity),
                                (torque, whole.input_torque)):
            assert (drawn.min(), drawn.max()) == (recorded.min(), recorded.max())
        assert tours[-1].efforts_everywhere
    short, long = tours
    # one revolution of each offset at 100 Hz (its ends rounded), and the sample before it
    for tour in tours:
        assert 2 * 101 <= tour.samples.time.size <= 2 * 102
    assert short.frames.size == long.frames.size == 2 * 21
