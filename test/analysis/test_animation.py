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
Animation: which sample each frame shows, what each frame draws, the offset tour.

The drawn pins are checked against the mechanism's equations written out here
(doc/mechanism.md) and against the recorded joint values, not against the drawing
code's own helpers; the recordings are synthetic runs (test/synthetic_run.py) and the golden
logs.
"""

import io
import math
import os
import re

import numpy as np
import pytest

from qrm_ros.analysis import animation
from qrm_ros.analysis import linkage_figure
from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.linkage import COLOURS, linkage_sizes
from qrm_ros.core.common.names import PARAMETERS_METADATA
from damaged_runs import decode_joint_state, encode_joint_state, put_together, take_apart
from synthetic_run import EFFORTS_SCHEDULE, made_up_efforts, PHASED, schedule_states
from repo_paths import TEST_DATA

PAPER = kin.Geometry.paper()


GOLDEN = TEST_DATA
PIN_TOLERANCE = 1e-9  # m


def _closed_form_points(geometry, input_angle, offset):
    """The pins by mechanism.md's equations: O1, P, C, the ram block, the lever's end."""
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    height = geometry.ram_height
    flywheel = math.atan2(r1 * math.sin(input_angle) + offset, r1 * math.cos(input_angle))
    crank = flywheel + geometry.crank_phase
    lever = math.atan2(r * math.cos(crank), h + r * math.sin(crank))
    lever_length = linkage_sizes(geometry).lever_length
    return {
        'input_centre': (0.0, offset), 'flywheel_centre': (0.0, 0.0), 'lever_pivot': (0.0, -h),
        'coupling_pin': (r1 * math.cos(input_angle), offset + r1 * math.sin(input_angle)),
        'crank_pin': (r * math.cos(crank), r * math.sin(crank)),
        'ram_block': (height * math.tan(lever), height - h),
        'lever_end': (lever_length * math.sin(lever), -h + lever_length * math.cos(lever)),
    }


def test_frame_plan_shows_the_last_sample_at_or_before_each_frame():
    time = np.arange(0, 1001) * 0.01  # 100 Hz for 10 s
    for start, end, fps, speed in ((None, None, 25.0, 1.0), (2.0, 3.0, 10.0, 1.0),
                                   (1.234, 9.87, 7.0, 3.5), (0.5, 0.6, 50.0, 0.1)):
        plan = animation.frame_plan(time, start, end, fps, speed)
        first = 0.0 if start is None else start
        last = 10.0 if end is None else end
        assert plan.sample.size == math.floor((last - first) * fps / speed + 1e-9) + 1
        assert np.allclose(plan.time, first + np.arange(plan.sample.size) * speed / fps,
                           rtol=0, atol=1e-12)
        for frame_time, sample in zip(plan.time, plan.sample):
            at_or_before = np.flatnonzero(time <= frame_time + 1e-12)
            assert sample == at_or_before[-1]


def test_frame_plan_takes_a_clock_that_jumps_back_in_stamp_order():
    time = np.array([0.0, 0.1, 0.2, 0.05, 0.15, 0.3])  # the clock jumped back after 0.2 s
    plan = animation.frame_plan(time, fps=20.0)
    assert plan.time.tolist() == pytest.approx([0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3])
    assert plan.sample.tolist() == [0, 3, 1, 4, 2, 2, 5]


@pytest.mark.parametrize('start, end, fps, speed, words', [
    (3.0, 3.0, 25.0, 1.0, 'empty span: --end (3 s) must be after --start (3 s)'),
    (5.0, 2.0, 25.0, 1.0, 'empty span'),
    (-1.0, None, 25.0, 1.0, '--start -1 s is outside the recording (allowed: 0.000 to 10.000 s)'),
    (11.0, 12.0, 25.0, 1.0, '--start 11 s is outside the recording'),
    (float('nan'), None, 25.0, 1.0, '--start and --end must be finite'),
    (None, None, 0.0, 1.0, '--fps must be a positive number of frames per second, got 0'),
    (None, None, float('inf'), 1.0, '--fps must be a positive number'),
    (None, None, 1e-300, 1.0, '--fps 1e-300 is out of range: allowed [0.1, 240] frames per '
                              'second'),
    (None, None, 1e6, 1.0, '--fps 1e+06 is out of range'),
    (None, None, 25.0, -2.0, '--speed must be a positive playback factor, got -2'),
    (None, None, 25.0, float('nan'), '--speed must be a positive playback factor, got nan'),
    (None, None, 50.0, 1e-3, '500001 frames (10 s of run at --fps 50 and --speed 0.001) are '
     'too many for .mp4 (at most 180000): shorten the span'),
])
def test_frame_plan_refuses_what_it_cannot_show(start, end, fps, speed, words):
    with pytest.raises(animation.AnimationError, match='^' + re.escape(words)):
        animation.frame_plan(np.arange(0, 1001) * 0.01, start, end, fps, speed)


def test_gif_frame_rates_are_those_a_gif_plays_exactly():
    for fps, delay in ((50.0, 2), (25.0, 4), (20.0, 5), (12.5, 8), (100 / 7, 7), (1.0, 100),
                       (0.5, 200)):
        animation.check_rates(fps, 1.0, '.gif')
        assert animation.gif_delay(fps) == delay
    for fps in (100.0, 60.0, 30.0, 24.0, 14.0, 0.3):
        with pytest.raises(animation.AnimationError, match='cannot be played by a GIF'):
            animation.check_rates(fps, 1.0, '.gif')
        animation.check_rates(fps, 1.0, '.mp4')


def test_drawn_pins_equal_the_mechanism_at_the_frames_sample(run_with_efforts):
    recording = recorded_run.read_recording(str(run_with_efforts))
    samples = recording.samples
    efforts = animation.read_efforts(str(run_with_efforts), samples)
    plan = animation.frame_plan(samples.time, fps=7.0)
    result = measurement.analyse(recording)
    span = slice(int(plan.sample.min()), int(plan.sample.max()) + 1)
    figure = linkage_figure.LinkageFigure(recording.geometry, samples.time[span],
                                          samples.ram_velocity[span], efforts[span])
    row_at = animation.segment_at(result)
    sizes = linkage_sizes(PHASED)
    checked = set()
    try:
        for index, rgb in animation.render_frames(figure, samples, plan.sample, row_at,
                                                  efforts):
            assert rgb.shape == (640, 800, 3) and rgb.dtype == np.uint8
            drawn = figure.drawn_points()
            theta, offset = samples.input_angle[index], samples.offset[index]
            expected = _closed_form_points(PHASED, theta, offset)
            for name in ('input_centre', 'flywheel_centre', 'lever_pivot', 'coupling_pin',
                         'crank_pin', 'ram_block'):
                assert np.abs(drawn[name] - expected[name]).max() <= PIN_TOLERANCE, name
            assert np.abs(drawn['lever'] - [expected['lever_pivot'], expected['lever_end']]
                          ).max() <= PIN_TOLERANCE
            assert np.abs(drawn['input_crank'] - [expected['input_centre'],
                                                  expected['coupling_pin']]).max() <= 1e-9
            assert np.abs(drawn['crank'] - [(0, 0), expected['crank_pin']]).max() <= 1e-9
            # and the recorded joint values (the node's, here the synthetic run's)
            crank = samples.flywheel_angle[index] + PHASED.crank_phase
            assert np.abs(drawn['crank_pin'] - PHASED.crank_radius * np.array(
                [math.cos(crank), math.sin(crank)])).max() <= PIN_TOLERANCE
            assert abs(drawn['ram_block'][0] - samples.ram_position[index]) <= PIN_TOLERANCE
            assert np.abs(drawn['ram_centre'] - drawn['ram_block']).max() <= 1e-12
            assert drawn['tool_tip'] == pytest.approx(
                (samples.ram_position[index] - 0.5 * sizes.ram_length,
                 sizes.ram_line_height - sizes.tool_drop), abs=PIN_TOLERANCE)
            # the traces' markers are at the sample, and so is the label
            assert drawn['cursor_time'] == samples.time[index]
            assert drawn['velocity_dot'].tolist() == [samples.time[index],
                                                      samples.ram_velocity[index]]
            assert drawn['torque_dot'].tolist() == [samples.time[index], efforts[index]]
            label = f't = {samples.time[index]:8.3f} s\noffset {offset * 1e3:+7.2f} mm'
            assert figure.label.get_text() == label
            row = row_at(samples.time[index])
            assert figure.ratios.get_text() == '\n\n' + animation.ratio_text(row)
            checked.add(offset)
    finally:
        figure.close()
    # frames at both offsets and along the ramp between
    assert {0.0, 0.012} < checked and len(checked) >= 5


def test_frame_label_gives_the_segments_measured_ratios(run_with_efforts):
    result = measurement.analyse(recorded_run.read_recording(str(run_with_efforts)))
    row = result.rows[1]
    assert animation.ratio_text(row) == (
        f'TR {row["time_ratio_measured"]:.4f}  SR {row["speed_ratio_measured"]:.4f}  '
        f'(measured, {row["stroke_pairs"]} pairs)')
    assert animation.segment_at(result)(row['start_time']) is row
    # on the offset ramp between the segments there is no steady segment
    between = 0.5 * (result.rows[0]['end_time'] + row['start_time'])
    assert animation.segment_at(result)(between) is None
    assert animation.ratio_text(None) == 'TR, SR: no whole stroke pair at steady settings here'


def test_progress_bar_on_a_terminal(tmp_path, run_with_efforts):
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    terminal = Terminal()
    recording = recorded_run.read_recording(str(run_with_efforts))
    count = animation.write_animation(recording, str(tmp_path / 'run.gif'), end=0.5, fps=10.0,
                                      progress_stream=terminal)
    assert count == 6
    shown = terminal.getvalue()
    assert shown.startswith('\rdrawing:   0%|') and '| 0/6 [' in shown
    assert shown.endswith(' ' * 20 + '\r')  # the bar is wiped when done (tqdm leave=False)


def test_efforts_are_the_recorded_input_torque_of_each_sample(run_with_efforts):
    samples = recorded_run.read_recording(str(run_with_efforts)).samples
    efforts = animation.read_efforts(str(run_with_efforts), samples)
    schedule_time = schedule_states(**EFFORTS_SCHEDULE)[0]
    assert efforts.tolist() == [made_up_efforts(t)[0] for t in schedule_time]


def test_efforts_stay_with_their_sample_when_the_first_message_is_excluded(
        tmp_path, run_with_efforts):
    recorded = take_apart(run_with_efforts.read_bytes())
    first = recorded.joint_states()[0]
    decoded = decode_joint_state(first[4])
    decoded.position[0] = float('nan')  # the analysis excludes it: its time zero moves on
    first[4] = encode_joint_state(decoded)
    path = tmp_path / 'first_excluded.mcap'
    path.write_bytes(put_together(recorded))
    samples = recorded_run.read_recording(str(path)).samples
    assert samples.time.size == len(recorded.joint_states()) - 1
    efforts = animation.read_efforts(str(path), samples)
    schedule_time = schedule_states(**EFFORTS_SCHEDULE)[0]
    assert efforts.tolist() == [made_up_efforts(t)[0] for t in schedule_time[1:]]


def test_no_efforts_recorded_means_no_torque_trace():
    path = os.path.join(GOLDEN, 'steady_positive_offset.mcap')
    samples = recorded_run.read_recording(path).samples
    assert animation.read_efforts(path, samples) is None


def test_a_run_with_a_cutting_load_shows_the_workpiece(tmp_path, run_with_efforts):
    recorded = take_apart(run_with_efforts.read_bytes())
    recorded.metadata[PARAMETERS_METADATA] = {'cutting_force': '1500.0',
                                              'cutting_length': '0.08'}
    path = tmp_path / 'cutting.mcap'
    path.write_bytes(put_together(recorded))
    assert animation.recorded_cutting_length(str(path)) == 0.08
    # no parameters recorded
    assert animation.recorded_cutting_length(str(run_with_efforts)) is None
    recorded.metadata[PARAMETERS_METADATA]['cutting_force'] = '0.0'
    path.write_bytes(put_together(recorded))
    assert animation.recorded_cutting_length(str(path)) is None  # no load, no workpiece
    samples = recorded_run.read_recording(str(path)).samples
    figure = linkage_figure.LinkageFigure(PHASED, samples.time, samples.ram_velocity,
                                          cutting_length=0.08)
    try:
        sizes = linkage_sizes(PHASED)
        (workpiece,) = [patch for patch in figure.axes.patches
                        if patch.get_facecolor()[:3] == COLOURS['workpiece_brown'][:3]]
        # the tool tip's span while the ram is within +/- cutting_length / 2 (dynamics.md)
        assert workpiece.get_x() == pytest.approx(-0.5 * sizes.ram_length - 0.04, abs=1e-15)
        assert workpiece.get_width() == pytest.approx(0.08, abs=1e-15)
    finally:
        figure.close()


def test_offset_tour_draws_the_recorded_torque(tmp_path, run_with_efforts, monkeypatch):
    drawn = []

    class Recorded(linkage_figure.LinkageFigure):
        def draw(self, *state, **options):
            frame = super().draw(*state, **options)
            drawn.append(self.drawn_points())
            return frame

    monkeypatch.setattr(animation, 'LinkageFigure', Recorded)
    result = measurement.analyse(recorded_run.read_recording(str(run_with_efforts)))
    animation.write_offset_tour(result, str(tmp_path / 'tour.gif'))
    samples = result.recording.samples
    indices = animation.offset_tour_samples(result)
    efforts = animation.read_efforts(str(run_with_efforts), samples)
    assert [d['torque_dot'].tolist() for d in drawn] == [
        [samples.time[i], efforts[i]] for i in indices]


# Two of each kind of damage or oddity by default; qrm_analyze's own fuzz test runs 300.
FUZZ_CASES = int(os.environ.get('QRM_ANIMATE_FUZZ_CASES', '14'))
