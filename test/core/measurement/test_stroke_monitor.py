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
"""The ROS-free stroke monitor against the closed form, sample by sample as the node feeds it."""

import math

import numpy as np
import pytest
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import state, stroke_times, time_ratio
from qrm_ros.core.measurement.stroke_monitor import MEASURED_FIGURES, SAMPLE_FIELDS, StrokeMonitor
from qrm_ros.core.measurement.strokes import find_stroke_pairs, measure_pair_efforts

NS = 1_000_000_000
GEOMETRY = Geometry.paper()


def feed(monitor, offset, speed, seconds, rate=1000.0, start_ns=NS, offsets=None):
    """Exact steady-running samples (core closed form); return every report."""
    reports = []
    for index in range(int(seconds * rate)):
        stamp = start_ns + round(index * NS / rate)
        angle = speed * (stamp - start_ns) / NS
        moving = offsets(index) if offsets else offset
        sample = state(GEOMETRY, moving, angle, speed)
        reports += monitor.add(stamp, float(sample.ram_position), float(sample.ram_velocity),
                               moving, 0.0, speed, 0.0, 0.0)
    return reports


@pytest.mark.parametrize('offset, speed', [(0.0, 2 * math.pi), (0.012, 2 * math.pi),
                                           (-0.01, -3.0)])
def test_steady_pairs_match_the_closed_form(offset, speed):
    reports = feed(StrokeMonitor(GEOMETRY), offset, speed, 3.5 * 2 * math.pi / abs(speed))
    assert len(reports) >= 2
    cutting, returning = stroke_times(GEOMETRY, offset, speed)
    for report in reports:
        assert report.steady and report.coupling_offset == offset
        assert set(report.measured) == set(MEASURED_FIGURES)
        assert report.measured['time_ratio'] == pytest.approx(
            time_ratio(GEOMETRY, offset, speed), rel=1e-6)
        assert report.measured['cutting_time'] == pytest.approx(cutting, abs=1e-6)
        # Theory is the core's, scaled to the speed: times and speeds, not just ratios.
        assert report.theory['cutting_time_theory'] == pytest.approx(cutting, rel=1e-14)
        assert report.theory['return_time_theory'] == pytest.approx(returning, rel=1e-14)
        assert report.pair_end - report.pair_start == pytest.approx(cutting + returning,
                                                                    abs=1e-6)
        assert all(np.isfinite(list(report.values().values())))


def test_clear_forgets_a_partial_pair_and_a_moving_offset_is_flagged():
    monitor = StrokeMonitor(GEOMETRY)
    feed(monitor, 0.0, 2 * math.pi, 0.7)
    monitor.clear()
    assert len(monitor) == 0
    reports = feed(StrokeMonitor(GEOMETRY), None, 2 * math.pi, 2.2,
                   offsets=lambda index: 1e-6 * index)
    assert reports and not any(r.offset_steady for r in reports)
    assert all(r.input_speed_steady for r in reports)


def test_collect_then_measure_reports_as_add_does_and_owns_its_samples():
    """The node's split (collect on the timer, measured in steps between) changes nothing."""
    whole = feed(StrokeMonitor(GEOMETRY), 0.012, 2 * math.pi, 3.5)
    monitor = StrokeMonitor(GEOMETRY)
    completed, stepping, stepped = [], [], []
    for index in range(3500):
        stamp = NS + index * NS // 1000
        sample = state(GEOMETRY, 0.012, 2 * math.pi * (stamp - NS) / NS, 2 * math.pi)
        found = monitor.collect(stamp, float(sample.ram_position), float(sample.ram_velocity),
                                0.012, 0.0, 2 * math.pi, 0.0, 0.0)
        if found is not None:
            completed.append(found)
            stepping.append(monitor.measure_steps(found))
        if stepping:  # one step a sample, while the buffer moves on
            try:
                next(stepping[0])
            except StopIteration as done:
                stepped += done.value
                stepping.pop(0)
    assert not stepping
    # Measured only now, after the monitor's buffer moved on: the copies are the pairs'.
    split = [report for found in completed for report in monitor.measure(found)]
    assert len(split) == len(stepped) == len(whole) >= 2
    for one, other, third in zip(split, whole, stepped):
        assert one == other == third


def test_numpy_views_measure_as_python_floats_do_bit_for_bit():
    """Wall-clock stamps (1.8e18 ns), jittered: the same figures as the offline path's lists."""
    rng = np.random.default_rng(7)
    start_ns = 1_795_000_000 * NS + 123_456_789
    monitor = StrokeMonitor(GEOMETRY)
    stamps, samples, completed = [], [], None
    offsets = [0.012 + (1e-5 * (index // 1500)) for index in range(10000)]
    for index in range(10000):  # 2.5 turns of 4 kHz samples
        stamp = start_ns + index * 250_000 + int(rng.integers(-40_000, 40_000))
        sample = state(GEOMETRY, offsets[index], 2 * math.pi * (stamp - start_ns) / NS,
                       2 * math.pi)
        values = (float(sample.ram_position), float(sample.ram_velocity), offsets[index],
                  1e-3 * (index % 3 == 0), 2 * math.pi, 5.0 + index * 1e-3, -2.0)
        stamps.append(stamp)
        samples.append(values)
        completed = monitor.collect(stamp, *values) or completed
    assert completed is not None
    reports = monitor.measure(completed)
    first_sample = stamps.index(completed.sample_stamps_ns[0])
    kept = slice(first_sample, first_sample + len(completed.sample_stamps_ns))
    origin = stamps[first_sample]
    time = [(ns - origin) / 1e9 for ns in stamps[kept]]  # Python ints and floats
    column = {name: [values[index] for values in samples[kept]]
              for index, name in enumerate(SAMPLE_FIELDS)}  # collect's argument order
    pairs = find_stroke_pairs(time, column['ram_position'], column['ram_velocity'])
    efforts = measure_pair_efforts(time, column['input_speed'], column['input_torque'],
                                   column['offset_force'], pairs)
    figures = {**pairs._asdict(), **efforts._asdict()}
    assert len(reports) == len(pairs.cutting_time) >= 1
    for index, report in enumerate(reports):
        assert report.measured == {name: float(figures[name][index])
                                   for name in MEASURED_FIGURES}
        first, last = int(pairs.first_sample[index]), int(pairs.last_sample[index])
        offsets_in = column['offset'][first:last + 1]
        assert report.offset_steady is (min(offsets_in) == max(offsets_in)
                                        and not any(column['offset_rate'][first:last]))
        assert report.coupling_offset == offsets_in[-1]
        assert report.pair_start == origin / 1e9 + float(pairs.cutting_start[index])
