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
Offline analysis against the closed form, on synthetic runs written without ROS.

The synthetic joint states are the core's exact states sampled at 100 Hz, so the measured
ratios may differ from theory only by the stroke finder's interpolation error, bounded by
(|w| dt)^3 = 2.5e-4 at 2 pi rad/s and 100 Hz (test_strokes derives that bound).
"""

import json
import math

import numpy as np
import pytest

from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import report
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.sampling_bounds import gap_after, GAP_SECONDS
from synthetic_run import samples_for, SCHEDULE

PAPER = kin.Geometry.paper()
TOLERANCE = (2 * math.pi * 0.01) ** 3


def test_segments_are_exactly_the_commanded_offsets(schedule_analysis):
    assert [row['offset'] for row in schedule_analysis.rows] == SCHEDULE
    assert len(schedule_analysis.transitions) == len(SCHEDULE) - 1
    for row in schedule_analysis.rows:
        assert row['stroke_pairs'] >= 3


@pytest.mark.parametrize('name', ['time_ratio', 'speed_ratio', 'peak_speed_ratio'])
def test_measured_ratios_match_closed_form(schedule_analysis, name):
    function = {'time_ratio': kin.time_ratio, 'speed_ratio': kin.speed_ratio,
                'peak_speed_ratio': kin.peak_speed_ratio}[name]
    for row in schedule_analysis.rows:
        expected = function(PAPER, row['offset'])
        assert row[f'{name}_theory'] == pytest.approx(expected, rel=1e-12)
        assert row[f'{name}_measured'] == pytest.approx(expected, rel=TOLERANCE)
        assert abs(row[f'{name}_relative_error']) < TOLERANCE


def test_unity_speed_ratio_offset_measures_one(schedule_analysis):
    row = schedule_analysis.rows[1]
    assert row['speed_ratio_measured'] == pytest.approx(1.0, rel=TOLERANCE)


def test_stroke_times_and_speeds_match_closed_form(schedule_analysis):
    for row in schedule_analysis.rows:
        cutting, returning = kin.stroke_times(PAPER, row['offset'], 2 * math.pi)
        assert row['cutting_time_measured'] == pytest.approx(cutting, rel=TOLERANCE)
        assert row['return_time_measured'] == pytest.approx(returning, rel=TOLERANCE)
        peak_cut, peak_ret = kin.peak_ram_speeds(PAPER, row['offset'], 2 * math.pi)
        assert row['peak_cutting_speed_measured'] == pytest.approx(peak_cut, rel=TOLERANCE)
        assert row['peak_return_speed_measured'] == pytest.approx(peak_ret, rel=TOLERANCE)


def test_reverse_running_gives_the_inverse_ratios():
    recording = recorded_run.Recording(
        'reverse', PAPER, samples_for([0.01], input_speed=-2 * math.pi), None)
    (row,) = measurement.analyse(recording).rows
    assert row['time_ratio_measured'] == pytest.approx(1 / kin.time_ratio(PAPER, 0.01),
                                                       rel=TOLERANCE)
    assert row['time_ratio_measured'] < 1.0


def test_coarse_sampling_is_flagged(capsys):
    coarse = recorded_run.Recording('coarse', PAPER, samples_for([0.01], rate=25.0), None)
    fine = recorded_run.Recording('fine', PAPER, samples_for([0.01], rate=100.0), None)
    (coarse_row,) = measurement.analyse(coarse).rows
    (fine_row,) = measurement.analyse(fine).rows
    assert coarse_row['samples_per_revolution'] == pytest.approx(25.0)
    assert fine_row['samples_per_revolution'] == pytest.approx(100.0)
    assert 'only 25 samples per input revolution' in report.format_table(
        measurement.analyse(coarse))
    assert 'warning' not in report.format_table(measurement.analyse(fine))


def _with_jump(samples, at, seconds):
    """Shift the stamps from sample `at` on: a pause (> 0, the motion resumes where it
    stopped) or a clock jump back (< 0)."""
    time = samples.time.copy()
    time[at:] += seconds
    return samples._replace(time=time)


@pytest.mark.parametrize('seconds', [3.0, 0.05, -2.0])
def test_a_gap_inside_a_steady_segment_splits_it_and_is_listed(seconds):
    steady = samples_for([0.01], hold=8.0)
    middle = steady.time.size // 2 + 7
    result = measurement.analyse(recorded_run.Recording('paused', PAPER, _with_jump(
        steady, middle, seconds), None))
    assert [(row['offset'], row['input_speed']) for row in result.rows] == [
        (0.01, 2 * math.pi)] * 2
    assert [(s.start, s.end) for s in result.segments] == [(0, middle),
                                                           (middle, steady.time.size)]
    (gap,) = result.transitions
    assert gap['kind'] == 'gap' and gap['offset_from'] == gap['offset_to'] == 0.01
    assert (f'gap of {seconds + 0.01:.3f} s' if seconds > 0
            else f'jumps back by {-seconds - 0.01:.3f} s') in gap['change']
    expected = kin.time_ratio(PAPER, 0.01)
    for row in result.rows:  # no stroke measured across the gap
        assert row['time_ratio_measured'] == pytest.approx(expected, rel=TOLERANCE)
        assert row['time_ratio_measured_std'] < TOLERANCE


def test_a_gap_of_a_few_periods_is_tolerated():
    steady = samples_for([0.01], hold=8.0)
    jittered = _with_jump(steady, 300, 0.019)  # a 2.9-period step: still one segment
    (row,) = measurement.analyse(recorded_run.Recording('late', PAPER, jittered, None)).rows
    assert row['stroke_pairs'] >= 6


def test_a_late_tick_at_a_high_rate_is_no_gap():
    """At 1 kHz three periods are 3 ms; a 20 ms hole (a loaded machine's late timer) is not a
    stall: one segment, its pairs measured (their sampling bounds widen near it)."""
    steady = samples_for([0.01], hold=8.0, rate=1000.0)
    hole = np.arange(3000, 3019)  # 19 ticks not published: a 20 ms step
    late = steady._make(None if field is None else np.delete(field, hole) for field in steady)
    assert gap_after(0.001) == GAP_SECONDS > 0.02
    (row,) = measurement.analyse(recorded_run.Recording('late', PAPER, late, None)).rows
    assert row['stroke_pairs'] >= 6
    assert row['time_ratio_measured'] == pytest.approx(kin.time_ratio(PAPER, 0.01),
                                                       rel=TOLERANCE)
    # A hole longer than 50 ms is a gap at any rate.
    hole = np.arange(3000, 3060)
    stalled = steady._make(None if field is None else np.delete(field, hole) for field in steady)
    result = measurement.analyse(recorded_run.Recording('stalled', PAPER, stalled, None))
    assert [t['kind'] for t in result.transitions] == ['gap']


def test_json_holds_null_where_a_figure_is_not_finite(capsys):
    recording = recorded_run.Recording('huge', PAPER, samples_for([0.01]), None)
    result = measurement.analyse(recording)
    result.rows[0]['time_ratio_measured'] = math.inf
    result.rows[0]['speed_ratio_measured'] = math.nan
    document = report.to_document(result)
    text = json.dumps(document, allow_nan=False)
    assert document['segments'][0]['time_ratio_measured'] is None
    assert json.loads(text)['segments'][0]['speed_ratio_measured'] is None
