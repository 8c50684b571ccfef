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
The shaper_sim node's stroke-pair reports on /diagnostics
(qrm_ros.node.shaper_sim.stroke_pair_reports).

Driven through ShaperSimNode.publish_at with synthetic 100 Hz stamps (the timer does exactly
that with the node clock), so the checks are deterministic and fast: the figures against the
closed forms, and the pairs measured a step at a time between the ticks.
"""

import math

import pytest
from qrm_ros.core.kinematics import peak_speed_ratio, speed_ratio, time_ratio
from qrm_ros.core.measurement.stroke_monitor import PairReport
from qrm_ros.node.shaper_sim.shaper_diagnostics import stroke_pair_status
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool

from shaper_harness import all_finite, H_PIVOT, NS, pair_values, R, R1, run_ticks


# TR and SR from 100 Hz samples (100 per turn, stamps jittered by +-1 ms): reversals, mid
# strokes and peaks are located between samples, and measured 2e-5 from the exact values;
# the tolerance leaves a 5x margin. Sampled exactly at reversals it would be ~1e-2.
RATIO_TOLERANCE = 1e-4
PERIOD_TOLERANCE = 1e-5  # s, on cutting + return time = one input turn


@pytest.mark.parametrize('offset, speed', [(0.0, 2 * math.pi), (0.01, 2 * math.pi),
                                           (-0.015, 2 * math.pi), (0.01, -2 * math.pi)])
def test_diagnostics_match_the_closed_form_for_a_steady_offset(harness, offset, speed):
    h = harness(spin_shaper=False, coupling_offset=offset, input_speed=speed)
    run_ticks(h.shaper, 5000 * NS, 3.5)
    h.wait_for(lambda: len(h.diagnostics) >= 2, what='two stroke-pair diagnostics')
    geometry = h.shaper.geometry
    for message in h.diagnostics:
        values = pair_values(message)
        assert message.status[0].name == 'shaper_sim: stroke pair'
        # diagnostic_updater's convention: the node in the name, the machine as hardware_id
        # (so a viewer's 'hardware_id: name' names the node once).
        assert message.status[0].hardware_id == 'qrm_shaper'
        assert values['offset_steady'] == 'true' and values['input_speed_steady'] == 'true'
        assert values['coupling_offset'] == offset and values['input_speed'] == speed
        assert values['cutting_time'] + values['return_time'] == pytest.approx(
            2 * math.pi / abs(speed), abs=PERIOD_TOLERANCE)
        assert values['time_ratio'] == pytest.approx(time_ratio(geometry, offset, speed),
                                                     rel=RATIO_TOLERANCE)
        assert values['speed_ratio'] == pytest.approx(speed_ratio(geometry, offset, speed),
                                                      rel=RATIO_TOLERANCE)
        assert values['peak_speed_ratio'] == pytest.approx(
            peak_speed_ratio(geometry, offset, speed), rel=RATIO_TOLERANCE)
        assert values['time_ratio_theory'] == pytest.approx(time_ratio(geometry, offset, speed),
                                                            rel=1e-14)
        # Independent closed forms (design note): eq. 28 at zero offset, eq. 25 for SR.
        if offset == 0.0:
            gap = 2 * math.asin(R / H_PIVOT)
            assert values['time_ratio'] == pytest.approx(
                (math.pi + gap) / (math.pi - gap), rel=RATIO_TOLERANCE)
        forward_sr = (H_PIVOT + R) * (R1 + offset) / ((H_PIVOT - R) * (R1 - offset))
        expected_sr = forward_sr if speed > 0 else 1 / forward_sr
        assert values['speed_ratio'] == pytest.approx(expected_sr, rel=RATIO_TOLERANCE)
        if speed < 0:  # reversed, the cut is the fast stroke: TR is the forward's inverse
            assert values['time_ratio'] < 1.0
            assert values['time_ratio'] == pytest.approx(
                1.0 / time_ratio(geometry, offset, -speed), rel=RATIO_TOLERANCE)
        assert values['cutting_time'] == pytest.approx(values['time_ratio']
                                                       * values['return_time'])


def _ticks_of_pair_steps(shaper):
    """Record, for every stroke-pair step the node runs, how many ticks came before it."""
    ticks, steps_at = [0], []
    publish_at, measure_steps = shaper.publish_at, shaper.stroke_pairs.monitor.measure_steps

    def counted_publish_at(stamp_ns):
        ticks[0] += 1
        return publish_at(stamp_ns)

    def recorded_steps(completed):
        steps = measure_steps(completed)
        while True:
            steps_at.append(ticks[0])
            try:
                next(steps)
            except StopIteration as done:
                return done.value
            yield

    shaper.publish_at = counted_publish_at
    shaper.stroke_pairs.monitor.measure_steps = recorded_steps
    return steps_at


def test_a_stroke_pair_is_measured_a_step_at_a_time_between_ticks(harness):
    """Out of time after a tick, a pair waits; it still moves a step every other tick."""
    h = harness(spin_shaper=False)
    shaper = h.shaper
    shaper.stroke_pairs.step_budget_ns = 0  # every tick out of time
    steps_at = _ticks_of_pair_steps(shaper)
    completed = []
    collect = shaper.stroke_pairs.monitor.collect

    def kept_collect(*sample):
        result = collect(*sample)
        if result is not None:
            completed.append(result)
        return result

    shaper.stroke_pairs.monitor.collect = kept_collect
    # Samples completed at about 1, 2 and 3 s (the first holds no whole pair); every step
    # has run before 3.5 s.
    run_ticks(shaper, 5000 * NS, 3.5, wait_for_reports=False)
    assert len(completed) == 3 and shaper.pair_reports_published == 2
    # Never two steps in one tick, and while steps wait, one every other tick.
    gaps = [later - earlier for earlier, later in zip(steps_at, steps_at[1:])]
    assert len(steps_at) > 3 * 8 and min(gaps) == 2
    assert sum(gap > 2 for gap in gaps) == len(completed) - 1  # between the samples' steps
    # The reports are those of the whole measurement at once, figure for figure.
    h.wait_for(lambda: len(h.diagnostics) == 2, what='both pairs reported')
    assert shaper.stroke_pairs.monitor.measure(completed[0]) == []
    for message, samples in zip(h.diagnostics, completed[1:]):
        whole, = shaper.stroke_pairs.monitor.measure(samples)
        values = pair_values(message)
        assert {name: values[name] for name in whole.measured} == whole.measured


def test_a_pair_within_the_budget_is_reported_by_the_tick_that_completed_it(harness):
    h = harness(spin_shaper=False)
    shaper = h.shaper
    shaper.stroke_pairs.step_budget_ns = 10 ** 12
    steps_at = _ticks_of_pair_steps(shaper)
    # Samples completed at about 1 s (no whole pair) and 2 s (one): each measured at once.
    run_ticks(shaper, 5000 * NS, 2.5, wait_for_reports=False)
    assert shaper.pair_reports_published == 1 and len(set(steps_at)) == 2


def test_pairs_are_still_reported_while_paused(harness):
    h = harness(spin_shaper=False)
    shaper = h.shaper
    shaper.stroke_pairs.step_budget_ns = 0
    run_ticks(shaper, 5000 * NS, 2.0, wait_for_reports=False)  # a pair completed at 1.94 s
    assert shaper.pair_reports_published == 0  # its steps wait, one every other tick
    shaper.on_pause(SetBool.Request(data=True), SetBool.Response())
    for _ in range(200):
        shaper.on_timer()
    assert shaper.pair_reports_published == 1


def test_a_moving_offset_is_flagged_and_nothing_is_ever_non_finite(harness):
    h = harness(spin_shaper=False, coupling_offset=-0.02, offset_rate_limit=0.01)
    h.shaper.set_parameters([Parameter('coupling_offset', value=0.0225)])  # 4.25 s of travel
    run_ticks(h.shaper, 10 * NS, 6.0)
    # Every pair reported, and received: the last one is the steady one.
    h.wait_for(lambda: len(h.diagnostics) == h.shaper.pair_reports_published >= 4
               and len(h.joint_states) >= 600, what='diagnostics and joint states')
    steady = [pair_values(m)['offset_steady'] for m in h.diagnostics]
    assert steady[:3] == ['false'] * 3 and steady[-1] == 'true'
    assert all(all_finite(m) for m in h.joint_states)
    assert h.joint_states[-1].position[4] == 0.0225


def test_a_figure_that_is_not_finite_is_never_shown_in_the_status_text():
    # While reversing, SR has no value (nan): the key-values leave it out, and the text
    # says n/a rather than nan.
    measured = {'time_ratio': 0.3732, 'speed_ratio': math.nan, 'peak_speed_ratio': math.inf,
                'mean_cutting_speed': math.nan, 'peak_cutting_speed': math.nan}
    report = PairReport(stamp_ns=5 * NS, pair_start=1.0, pair_end=2.0, coupling_offset=0.01,
                        input_speed=-2 * math.pi, offset_steady=True, input_speed_steady=True,
                        measured=measured, theory={})
    status, = stroke_pair_status(report, [], 'none', 0.3, 'mean').status
    assert status.message.startswith('TR 0.3732, SR n/a (peak n/a)')
    assert 'nan' not in status.message and 'inf' not in status.message
    assert all(v.value not in ('nan', 'inf') for v in status.values)
    assert 'speed_ratio' not in {v.key for v in status.values}


def test_a_pair_across_a_gap_in_publication_is_not_steady(harness):
    """A stalled timer: no tick for 0.35 s mid-pair; the pair across it is not steady."""
    h = harness(spin_shaper=False, coupling_offset=0.01)
    before = run_ticks(h.shaper, 5000 * NS, 2.55)
    gap_start = before[-1]
    after = run_ticks(h.shaper, gap_start + int(0.35 * NS), 3.0, seed=11)
    gap_end = after[0]
    h.wait_for(lambda: len(h.diagnostics) == h.shaper.pair_reports_published >= 3,
               what='the stroke-pair diagnostics')
    spans, kept = 0, 0
    for message in h.diagnostics:
        values = pair_values(message)
        start, end = values['pair_start'] * NS, values['pair_end'] * NS
        text = message.status[0].message
        if start < gap_end and end > gap_start:  # measured across the gap
            spans += 1
            assert values['sampled_without_gap'] == 'false', values
            assert text.endswith('NOT steady (a gap in the samples)'), text
        else:
            kept += 1
            assert values['sampled_without_gap'] == 'true', values
            assert text.endswith(', steady'), text
    assert spans >= 1 and kept >= 2
