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
The live stroke over DDS: stroke_length at its rate limit, the crank radius joint, the
time-ratio hold, refusals, a reset during a stroke change.

Checked against independent derivations: published velocities against differences of the
published positions; the crank radius against r = S h / sqrt(4 H^2 + S^2) written out; the
held time ratio as measured from published stroke pairs.
"""

import dataclasses
import math

import pytest
from qrm_ros.analysis import analyse_file, incompleteness
from qrm_ros.core.design.cutting_speed_hold import hold_offset
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import TIME_RATIO_STATUS
from qrm_ros.core.kinematics.stroke_timing import time_ratio
from qrm_ros.node.offline.offline_sim import Simulation
from qrm_ros.node.offline.scenario import scenario_from_mapping
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from shaper_harness import H_PIVOT, NS
from test_shaper_sim_motor import pair_reports

RAM_HEIGHT = 0.2


def radius_for(stroke):
    """The crank radius of a stroke, written out (doc/mechanism.md)."""
    return stroke * H_PIVOT / math.sqrt(4.0 * RAM_HEIGHT ** 2 + stroke ** 2)


def publish_for(h, start_ns, seconds, rate=1000.0):
    """Publish at rate (synthetic stamps); wait for the probe now and then (its queue)."""
    period = round(NS / rate)
    count = len(h.joint_states)
    stamps = [start_ns + period * i for i in range(1, int(seconds * rate) + 1)]
    for index, stamp in enumerate(stamps, 1):
        assert h.shaper.publish_at(stamp)
        if index % 400 == 0 or index == len(stamps):
            h.wait_for(lambda: len(h.joint_states) == count + index, what='joint states')
    h.shaper.wait_for_pair_reports(timeout=30.0)
    return stamps[-1]


def set_ok(h, **values):
    results = h.shaper.set_parameters([Parameter(k, value=v) for k, v in values.items()])
    assert all(result.successful for result in results), [r.reason for r in results]


def refusal(h, **values):
    result = h.shaper.set_parameters_atomically(
        [Parameter(k, value=v) for k, v in values.items()])
    assert not result.successful
    return result.reason


def test_stroke_change_at_the_rate_limit_keeps_every_joint_continuous_and_exact(harness):
    h = harness(spin_shaper=False, stroke_rate_limit=0.05, coupling_offset=0.008)
    now = publish_for(h, 5 * NS, 0.3)
    set_ok(h, stroke_length=0.06)
    now = publish_for(h, now, 3.2)
    messages = h.joint_states
    dt = 1e-3
    radii = [m.position[5] for m in messages]
    assert radii[0] == 0.0505 and radii[-1] == pytest.approx(radius_for(0.06), rel=1e-14)
    moving = [i for i in range(1, len(messages) - 1) if messages[i].velocity[5] != 0.0]
    assert len(moving) > 2500  # 0.1398 m of stroke at 0.05 m/s: 2.8 s
    for i in moving[1:-1]:
        before, middle, after = messages[i - 1], messages[i], messages[i + 1]
        # Central differences of the published positions against the published rates
        # (ram, lever, crank radius), to the differences' own error (dt^2 terms); without
        # the crank radius's terms the ram's would be some 0.04 m/s off.
        for joint, tolerance in ((3, 1e-4), (2, 1e-3), (5, 1e-9)):
            derivative = (after.position[joint] - before.position[joint]) / (2 * dt)
            assert abs(derivative - middle.velocity[joint]) < tolerance, (joint, i)
        # The stroke moves at its limit: dS/dt = -0.05 m/s, through dr/dS.
        stroke = 2 * RAM_HEIGHT * middle.position[5] / math.sqrt(
            H_PIVOT ** 2 - middle.position[5] ** 2)
        slope = 4 * RAM_HEIGHT ** 2 * H_PIVOT / (4 * RAM_HEIGHT ** 2 + stroke ** 2) ** 1.5
        assert middle.velocity[5] == pytest.approx(-0.05 * slope, rel=1e-9)
        assert all(map(math.isfinite, middle.effort)) and len(middle.effort) == 6
    # Positions continuous throughout: no step bigger than the fastest rate allows.
    for before, after in zip(messages, messages[1:]):
        for joint in (2, 3, 5):
            fastest = max(abs(before.velocity[joint]), abs(after.velocity[joint]))
            assert abs(after.position[joint] - before.position[joint]) <= fastest * dt * 1.01 \
                + 1e-12


def steady_pairs(h, since):
    return [p for p in pair_reports(h.diagnostics[since:])
            if p['offset_steady'] == 'true' and p['stroke_steady'] == 'true']


def test_time_ratio_hold_measured_before_and_after_a_stroke_change(harness):
    h = harness(spin_shaper=False, stroke_rate_limit=0.1, offset_rate_limit=0.02)
    now = publish_for(h, 5 * NS, 0.2)
    set_ok(h, time_ratio_target=1.8)
    mark = len(h.diagnostics)
    now = publish_for(h, now, 4.0)
    pairs = steady_pairs(h, mark)
    assert len(pairs) >= 2
    for pair in pairs:
        # Measured from the published samples, against the target.
        assert abs(pair['time_ratio'] / 1.8 - 1.0) < 1e-3, pair
        assert pair['time_ratio_target'] == 1.8 and abs(pair['time_ratio_error']) < 1e-3
        assert pair['stroke_length'] == pytest.approx(0.19983, abs=1e-5)
    set_ok(h, stroke_length=0.06)
    mark = len(h.diagnostics)
    now = publish_for(h, now, 5.0)
    pairs = steady_pairs(h, mark)
    assert len(pairs) >= 2
    for pair in pairs:
        assert abs(pair['time_ratio'] / 1.8 - 1.0) < 1e-3, pair
        assert pair['stroke_length'] == pytest.approx(0.06, rel=1e-12)
        assert pair['crank_radius'] == pytest.approx(radius_for(0.06), rel=1e-12)
    # Without the hold the short stroke would lose its quick return.
    short = dataclasses.replace(Geometry.paper(), crank_radius=radius_for(0.06))
    assert time_ratio(short, 0.0) < 1.21
    statuses = [m.status[0] for m in h.diagnostics if m.status[0].name == TIME_RATIO_STATUS]
    assert statuses and all(status.level == b'\x00' for status in statuses)


def test_stroke_and_hold_refusals_name_value_unit_and_range(harness):
    h = harness(spin_shaper=False)
    reason = refusal(h, stroke_length=0.5)
    assert reason.startswith('stroke_length = 0.5 refused: outside the allowed range 0 (the '
                             'stroke of crank_radius) or 0 < stroke_length <= 0.315645 m')
    assert 'max_crank_radius = 0.07 m' in reason
    assert 'stroke_length = -0.1 refused' in refusal(h, stroke_length=-0.1)
    assert 'read-only' in refusal(h, max_crank_radius=0.09)
    reason = refusal(h, time_ratio_target=30.0)
    assert reason.startswith('time_ratio_target = 30.0 refused: time ratio 30 is out of reach')
    assert 'give 0.537448 to 17.3064' in reason
    set_ok(h, cutting_length=0.15)
    assert 'shorter than cutting_length = 0.15 m' in refusal(h, stroke_length=0.1)
    set_ok(h, time_ratio_target=2.0)
    assert 'both command the offset' in refusal(h, cutting_speed_target=0.3)
    assert 'commanded by time_ratio_target' in refusal(h, coupling_offset=0.01)
    # One atomic call may set one and clear the other.
    assert h.shaper.set_parameters_atomically([
        Parameter('time_ratio_target', value=0.0),
        Parameter('cutting_speed_target', value=0.3)]).successful
    set_ok(h, cutting_speed_target=0.0, stroke_length=0.16)
    h.shaper.publish_at(5 * NS)
    assert h.shaper.stroke_moving
    # The motor drive takes a moving stroke over, and moves it on (test_stroke_under_...).
    set_ok(h, drive='motor')
    h.shaper.publish_at(6 * NS)
    assert h.shaper.stroke_moving and h.shaper.stepper.stroke.rate == -0.01
    set_ok(h, stroke_length=0.2)
    assert 'stroke_length = 0.5 refused' in refusal(h, stroke_length=0.5)
    assert 'shorter than cutting_length = 0.15 m' in refusal(h, stroke_length=0.1)


def test_stroke_length_descriptor_publishes_the_slot_s_range(harness):
    """[0, the stroke at max_crank_radius]: 0 is the stroke of crank_radius."""
    h = harness(spin_shaper=False)
    descriptor = h.shaper.describe_parameter('stroke_length')
    bounds = descriptor.floating_point_range[0]
    # 2 H r / sqrt(h^2 - r^2) at the slot's 0.07 m, written out.
    largest = 2 * RAM_HEIGHT * 0.07 / math.sqrt(H_PIVOT ** 2 - 0.07 ** 2)
    assert (bounds.from_value, bounds.step) == (0.0, 0.0)
    assert bounds.to_value == pytest.approx(largest, rel=1e-12)
    assert 'crank radius up to max_crank_radius' in descriptor.additional_constraints


def test_unreachable_after_a_stroke_change_holds_the_nearest_offset_with_a_warning(harness):
    h = harness(spin_shaper=False)
    set_ok(h, time_ratio_target=10.0)  # reachable at 200 mm, not at 60 mm
    h.wait_for(lambda: any(m.status[0].name == TIME_RATIO_STATUS for m in h.diagnostics),
               what='the hold status')
    set_ok(h, stroke_length=0.06)
    h.wait_for(lambda: [m for m in h.diagnostics if m.status[0].name == TIME_RATIO_STATUS
                        and m.status[0].level == b'\x01'], what='a WARN time ratio status')
    warn = [m.status[0] for m in h.diagnostics if m.status[0].name == TIME_RATIO_STATUS][-1]
    assert 'out of reach at stroke 0.06 m' in warn.message and 'nearest' in warn.message
    values = {item.key: item.value for item in warn.values}
    assert float(values['offset_command']) == pytest.approx(0.0225)
    assert h.shaper.stepper.offset_command == pytest.approx(0.0225)
    # Back to the long stroke: in reach again, the exact offset and an OK status.
    count = len(h.diagnostics)
    set_ok(h, stroke_length=0.0)
    h.wait_for(lambda: [m for m in h.diagnostics[count:]
                        if m.status[0].name == TIME_RATIO_STATUS
                        and m.status[0].level == b'\x00'], what='an OK time ratio status')
    assert time_ratio(Geometry.paper(), h.shaper.stepper.offset_command) == pytest.approx(
        10.0, rel=1e-9)


@pytest.mark.parametrize('drive', ['speed', 'motor'])
def test_reset_during_a_stroke_change_returns_to_the_stroke_parameter(harness, drive):
    h = harness(spin_shaper=False, drive=drive, stroke_rate_limit=0.02)
    now = publish_for(h, 5 * NS, 0.1)
    set_ok(h, stroke_length=0.1)
    now = publish_for(h, now, 0.5)
    assert h.joint_states[-1].velocity[5] < 0.0  # moving
    response = h.shaper.on_reset(Trigger.Request(), Trigger.Response())
    assert response.success and 'stroke 0.1 m' in response.message
    count = len(h.joint_states)
    publish_for(h, now, 0.05)
    first = h.joint_states[count]
    assert first.position[0] == 0.0
    assert first.position[5] == pytest.approx(radius_for(0.1), rel=1e-14)
    assert first.velocity[5] == 0.0 and all(map(math.isfinite, first.effort))


def test_cutting_speed_hold_follows_a_stroke_change(harness):
    h = harness(spin_shaper=False)
    set_ok(h, cutting_speed_target=0.25)
    base = Geometry.paper()
    assert h.shaper.stepper.offset_command == hold_offset(base, 2 * math.pi, 0.25,
                                                          'mean').offset
    set_ok(h, stroke_length=0.1)
    short = dataclasses.replace(base, crank_radius=radius_for(0.1))
    expected = hold_offset(short, 2 * math.pi, 0.25, 'mean').offset
    assert h.shaper.stepper.offset_command == pytest.approx(expected, rel=1e-9)
    assert expected != pytest.approx(hold_offset(base, 2 * math.pi, 0.25, 'mean').offset)


def test_a_stroke_length_at_start_up_is_a_command_from_crank_radius(harness):
    h = harness(spin_shaper=False, stroke_length=0.1, stroke_rate_limit=0.5)
    assert h.shaper.stepper.stroke.stroke == pytest.approx(0.19983, abs=1e-5)
    publish_for(h, 5 * NS, 0.5)
    first, last = h.joint_states[0], h.joint_states[-1]
    # The crank pin starts at crank_radius and moves from there: no step to the command.
    assert first.position[5] == 0.0505 and first.velocity[5] < 0.0
    assert last.position[5] == pytest.approx(radius_for(0.1), rel=1e-14)
    assert last.velocity[5] == 0.0


def test_the_markers_draw_the_crank_pin_at_the_published_radius(harness):
    h = harness(spin_shaper=False, stroke_rate_limit=0.05, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 10)
    now = publish_for(h, 5 * NS, 0.1)
    set_ok(h, stroke_length=0.1)
    publish_for(h, now, 0.7)
    assert h.shaper.publish_markers()
    h.wait_for(lambda: arrays, what='markers')
    angle, flywheel, _, _, offset, radius = h.joint_states[-1].position
    assert h.joint_states[-1].velocity[5] < 0.0  # drawn mid-change
    crank_pin = {(m.ns, m.id): m for m in arrays[-1].markers}['pins', 0].points[1]
    assert (crank_pin.x, crank_pin.y) == pytest.approx(
        (radius * math.cos(flywheel), radius * math.sin(flywheel)), abs=1e-12)


def test_stroke_change_under_the_motor_drive_keeps_every_joint_continuous(harness):
    """The motor drive's equation of motion carries r(t): published rates are derivatives."""
    h = harness(spin_shaper=False, drive='motor', stroke_rate_limit=0.05,
                coupling_offset=0.008, ram_friction=20.0)
    now = publish_for(h, 5 * NS, 0.3)
    set_ok(h, stroke_length=0.06)
    now = publish_for(h, now, 3.2)
    messages = h.joint_states
    dt = 1e-3
    assert messages[-1].position[5] == pytest.approx(radius_for(0.06), rel=1e-14)
    moving = [i for i in range(1, len(messages) - 1) if messages[i].velocity[5] != 0.0]
    assert len(moving) > 2500  # 0.1398 m of stroke at 0.05 m/s: 2.8 s
    for i in moving[1:-1]:
        before, middle, after = messages[i - 1], messages[i], messages[i + 1]
        # Central differences of the published positions against the published rates: the
        # ram's, the lever's, the crank radius's and the input's (its speed fluctuates).
        for joint, tolerance in ((3, 1e-4), (2, 1e-3), (5, 1e-9), (0, 1e-3)):
            step = after.position[joint] - before.position[joint]
            if joint == 0:
                step = math.remainder(step, 2 * math.pi)
            assert abs(step / (2 * dt) - middle.velocity[joint]) < tolerance, (joint, i)
        assert all(map(math.isfinite, middle.effort)) and len(middle.effort) == 6
        # The stroke screw's force is published (the lever torque's share through dpsi/dr).
        assert middle.effort[5] != 0.0
    for before, after in zip(messages, messages[1:]):
        for joint in (2, 3, 5):
            fastest = max(abs(before.velocity[joint]), abs(after.velocity[joint]))
            assert abs(after.position[joint] - before.position[joint]) <= fastest * dt * 1.01 \
                + 1e-12


def test_time_ratio_hold_follows_a_stroke_change_under_the_motor_drive(harness):
    """The hold recomputes on a stroke change under the motor too (its offset, not TR)."""
    h = harness(spin_shaper=False, drive='motor', stroke_rate_limit=0.1,
                offset_rate_limit=0.02)
    set_ok(h, time_ratio_target=1.8)
    base = Geometry.paper()
    first = h.shaper.stepper.offset_command
    now = publish_for(h, 5 * NS, 0.2)
    set_ok(h, stroke_length=0.06)
    short = dataclasses.replace(base, crank_radius=radius_for(0.06))
    # The exact inverse at the new stroke: TR there is the target (eq. 28's closed form).
    assert time_ratio(short, h.shaper.stepper.offset_command) == pytest.approx(1.8, rel=1e-9)
    assert h.shaper.stepper.offset_command != pytest.approx(first, rel=1e-3)
    now = publish_for(h, now, 3.0)
    assert h.shaper.stepper.stroke.stroke == 0.06
    assert h.shaper.stepper.offset == h.shaper.stepper.offset_command
    set_ok(h, time_ratio_target=0.0, cutting_speed_target=0.25)
    expected = hold_offset(short, 2 * math.pi, 0.25, 'mean').offset
    assert h.shaper.stepper.offset_command == pytest.approx(expected, rel=1e-9)


@pytest.mark.slow
def test_a_motor_drive_run_with_a_stroke_change_analyses_whole(tmp_path):
    """Simulated offline and analysed: every sample passes the closed-form checks."""
    path = tmp_path / 'motor_stroke.mcap'
    Simulation(scenario_from_mapping({
        'parameters': {'drive': 'motor', 'cutting_force': 400.0, 'ram_friction': 20.0,
                       'cutting_length': 0.05, 'stroke_rate_limit': 0.05},
        'duration': 12.0,
        'events': [{'at': 3.0, 'set': {'stroke_length': 0.06}},
                   {'at': 8.0, 'set': {'time_ratio_target': 1.8}}]}), str(path)).run()
    result = analyse_file(str(path), progress_stream=None)
    assert not incompleteness(result.recording) and result.recording.problem is None
    assert [row['stroke_length'] for row in result.rows] == pytest.approx(
        [0.19983, 0.06, 0.06], abs=1e-5)
    assert 'a stroke change' in result.transitions[0]['change']
    # The short stroke loses its quick return; the hold gives it back (under the motor the
    # speed fluctuates, so the measured ratio is within a few 1e-3 of the closed form's).
    assert result.rows[1]['time_ratio_measured'] < 1.22
    assert result.rows[2]['time_ratio_measured'] == pytest.approx(1.8, rel=5e-3)
