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
The analysis with a live stroke: segments split on a stroke change, each measured at its
recorded crank radius and reporting it; the golden logs (five joints) analyse as before.
"""

import dataclasses
import math

import numpy as np
import pytest

from qrm_ros.analysis import animation_window
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis.animation import offset_tour_samples, render_frames, write_offset_tour
from qrm_ros.analysis.linkage_figure import LinkageFigure
from qrm_ros.analysis.measurement import analyse, measure_segment, segment_geometry
from qrm_ros.analysis.recorded_run import read_recording
from qrm_ros.analysis.streamed_run import analyse_file
from qrm_ros.analysis.segments import split_segments
from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke, Geometry
from qrm_ros.core.kinematics.mechanism_state import state
from qrm_ros.core.common.names import PUBLISHED_JOINT_NAMES
from qrm_ros.core.stepping.stepping import ShaperStepper
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp
from qrm_ros.core.kinematics.stroke_timing import time_ratio

PAPER = Geometry.paper()
RATE = 1000  # Hz


def stroke_change_samples():
    """3 s at the paper's stroke, a change to 60 mm at 0.1 m/s, 3 s there (1 kHz)."""
    stepper = ShaperStepper(PAPER, 2 * math.pi, 0.0, 20.0, 0.005,
                            StrokeRamp(PAPER, 0.07, float(PAPER.ram_stroke), 0.1))
    rows = []
    for index in range(int(7.5 * RATE)):
        stamp = index * 10 ** 9 // RATE
        if index == 3 * RATE:
            stepper.set_stroke_command(0.06)
        s = stepper.advance_to(stamp)
        radius_rate, _ = stepper.stroke.crank_radius_rates()
        rows.append((stamp / 1e9, stepper.input_angle, stepper.input_speed, s.flywheel_angle,
                     s.flywheel_speed, s.ram_position, s.ram_velocity, stepper.offset,
                     stepper.offset_rate, stepper.stroke.crank_radius, radius_rate))
    table = np.array(rows)
    return recorded_run.Samples(*table[:, :9].T, None, None, table[:, 9], table[:, 10])


def test_a_stroke_change_splits_the_segments_and_each_reports_its_stroke():
    samples = stroke_change_samples()
    segments, transitions = split_segments(samples)
    assert [segment.crank_radius for segment in segments] == [
        PAPER.crank_radius, pytest.approx(crank_radius_for_stroke(0.06, 0.113, 0.2),
                                          rel=1e-15)]
    assert 'a stroke change' in transitions[0]['change']
    # The ramp's samples belong to no segment.
    moving = np.flatnonzero(samples.crank_radius_rate != 0.0)
    assert segments[0].end <= moving[0] and segments[1].start > moving[-1]
    for segment, stroke in zip(segments, (float(PAPER.ram_stroke), 0.06)):
        geometry = segment_geometry(PAPER, segment)
        assert float(geometry.ram_stroke) == pytest.approx(stroke, rel=1e-12)
        row = measure_segment(samples, segment, geometry)
        assert row['stroke_pairs'] >= 2
        # Measured from the samples against the closed form at the segment's radius.
        assert row['time_ratio_measured'] == pytest.approx(time_ratio(geometry, 0.0),
                                                           rel=1e-4)
    assert row['time_ratio_measured'] < 1.21  # the short stroke's lost quick return


def test_a_recording_without_the_crank_radius_joint_is_one_geometry():
    samples = stroke_change_samples()._replace(crank_radius=None, crank_radius_rate=None)
    segments, _ = split_segments(samples)
    assert all(segment.crank_radius is None for segment in segments)
    assert segment_geometry(PAPER, segments[0]) is PAPER


def test_the_animation_draws_the_recorded_crank_radius():
    samples = stroke_change_samples()
    figure = LinkageFigure(PAPER, samples.time, samples.ram_velocity)
    try:
        for index in (100, 3500, 7000):  # before, during and after the stroke change
            for _ in render_frames(figure, samples, [index], lambda time: None):
                pass
            drawn = figure.drawn_points()
            radius = samples.crank_radius[index]
            geometry = dataclasses.replace(PAPER, crank_radius=float(radius))
            expected = state(geometry, samples.offset[index], samples.input_angle[index], 1.0)
            assert np.hypot(*drawn['crank_pin']) == pytest.approx(radius, rel=1e-12)
            assert drawn['ram_block'][0] == pytest.approx(expected.ram_position, abs=1e-12)
    finally:
        figure.close()


def test_the_animation_draws_the_guides_and_workpiece_at_the_stroke_in_force():
    """Each frame's guides span the stroke in force plus the ram (drawn sizes kept)."""
    samples = stroke_change_samples()
    figure = LinkageFigure(PAPER, samples.time, samples.ram_velocity, None, 0.04,
                           float(np.max(samples.crank_radius)))
    try:
        spans = []
        for index in (100, 3500, 7000):  # before, during and after the stroke change
            for _ in render_frames(figure, samples, [index], lambda time: None):
                pass
            radius, h, height = samples.crank_radius[index], 0.113, 0.2
            stroke = 2 * height * radius / math.sqrt(h * h - radius * radius)
            guide = figure.drawn_points()['guide']
            assert guide == pytest.approx(
                [-0.5 * (stroke + figure.sizes.ram_length),
                 0.5 * (stroke + figure.sizes.ram_length)], rel=1e-12)
            spans.append(guide[1] - guide[0])
        assert spans[0] > spans[1] > spans[2]
        assert spans[0] - spans[2] == pytest.approx(float(PAPER.ram_stroke) - 0.06, rel=1e-9)
    finally:
        figure.close()


def test_the_offset_tour_shows_each_recorded_stroke():
    samples = stroke_change_samples()
    recording = recorded_run.Recording('', PAPER, samples, None)
    result = analyse(recording)
    indices = offset_tour_samples(result, fps=20.0)
    radii = np.unique(np.round(samples.crank_radius[indices], 12))
    assert radii.tolist() == pytest.approx(
        [crank_radius_for_stroke(0.06, 0.113, 0.2), PAPER.crank_radius], rel=1e-12)
    # One revolution (1 s at 2 pi rad/s) of each, in recording order, at 20 frames a second.
    assert indices.size == pytest.approx(40, abs=2) and np.all(np.diff(indices) > 0)


def write_six_joint_run(path, samples):
    """Write samples as the node's six-joint joint states (the crank radius's joint last)."""
    from mcap.writer import Writer
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    type_name = 'sensor_msgs/msg/JointState'
    types = store.types
    with open(path, 'wb') as handle:
        writer = Writer(handle)
        writer.start(profile='ros2', library='qrm_ros test stroke segments')
        schema = writer.register_schema(type_name, 'ros2msg',
                                        store.generate_msgdef(type_name, ros_version=2)[0]
                                        .encode())
        channel = writer.register_channel('/joint_states', 'cdr', schema)
        writer.add_metadata('qrm_ros.geometry', {k: repr(float(v)) for k, v in
                                                 PAPER.as_dict().items()})
        # The lever, as the node publishes it: the ram sits at H tan(lever) (mechanism.md).
        lever = np.arctan(samples.ram_position / PAPER.ram_height)
        lever_speed = samples.ram_velocity * np.cos(lever) ** 2 / PAPER.ram_height
        for i, t in enumerate(samples.time):
            stamp_ns = 1_700_000_000 * 10 ** 9 + int(round(t * 1e9))
            message = types[type_name](
                header=types['std_msgs/msg/Header'](stamp=types['builtin_interfaces/msg/Time'](
                    sec=stamp_ns // 10 ** 9, nanosec=stamp_ns % 10 ** 9), frame_id='shaper_base'),
                name=list(PUBLISHED_JOINT_NAMES),
                position=np.array([samples.input_angle[i], samples.flywheel_angle[i], lever[i],
                                   samples.ram_position[i], samples.offset[i],
                                   samples.crank_radius[i]]),
                velocity=np.array([samples.input_speed[i], samples.flywheel_speed[i],
                                   lever_speed[i],
                                   samples.ram_velocity[i], samples.offset_rate[i],
                                   samples.crank_radius_rate[i]]),
                effort=np.zeros(0))
            writer.add_message(channel, log_time=stamp_ns, publish_time=stamp_ns,
                               data=bytes(store.serialize_cdr(message, type_name)), sequence=i)
        writer.finish()


def test_a_recorded_stroke_change_is_read_and_streamed_alike(tmp_path):
    """The whole-run reading and qrm_analyze's streamed one find the same two strokes."""
    path = str(tmp_path / 'stroke.mcap')
    write_six_joint_run(path, stroke_change_samples())
    whole = analyse(read_recording(path))
    streamed = analyse_file(path, {})
    assert [row['stroke_length'] for row in whole.rows] == [
        pytest.approx(float(PAPER.ram_stroke), rel=1e-12), pytest.approx(0.06, rel=1e-12)]
    assert whole.rows == streamed.rows and whole.transitions == streamed.transitions
    assert 'a stroke change' in whole.transitions[0]['change']


def test_the_streamed_offset_tour_is_the_whole_run_tour_at_each_stroke(tmp_path):
    """qrm_main's tour read from the file alone draws what the whole-run tour draws."""
    path = str(tmp_path / 'stroke.mcap')
    write_six_joint_run(path, stroke_change_samples())
    assert write_offset_tour(analyse(read_recording(path)), str(tmp_path / 'whole.gif'))
    streamed = analyse_file(path, {}, progress_stream=None)
    assert animation_window.write_window_tour(streamed, str(tmp_path / 'window.gif'),
                                              trace_bins=10 ** 9)  # every sample drawn
    assert (tmp_path / 'window.gif').read_bytes() == (tmp_path / 'whole.gif').read_bytes()
