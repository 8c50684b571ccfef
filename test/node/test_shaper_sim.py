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
The shaper_sim node in-process, over real rclpy and DDS (no mocks).

Diagnostics are driven through ShaperSimNode.publish_at with synthetic 100 Hz stamps (the
timer does exactly that with the node clock), so those checks are deterministic and fast;
services, pause and simulated time go through a spinning executor.
"""

import itertools
import math
import time

import pytest
from qrm_ros.core.kinematics import peak_speed_ratio, speed_ratio, state, time_ratio
from qrm_ros.node import shaper_sim
from qrm_ros.node.linkage_markers import linkage_marker_array, MARKER_KEYS, MOVING_KEYS
from qrm_ros.node.shaper_sim import JOINT_NAMES, PARAMETERS, ShaperSimNode
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import Marker, MarkerArray

from ros_probe import call, stamp_ns
from shaper_harness import NS, pair_values, run_ticks

R1, R, H_PIVOT = 0.025, 0.0505, 0.113


def all_finite(message):
    return all(map(math.isfinite, list(message.position) + list(message.velocity)))


# Parameters -------------------------------------------------------------------------------

def test_parameters_are_declared_with_units_ranges_and_read_only_flags(harness):
    h = harness(spin_shaper=True)
    request = DescribeParameters.Request(names=list(PARAMETERS))
    descriptors = {d.name: d for d in h.call(
        DescribeParameters, '/shaper_sim/describe_parameters', request).descriptors}
    read_only = {name for name, d in descriptors.items() if d.read_only}
    assert read_only == {'coupling_radius', 'crank_radius', 'pivot_distance', 'ram_height',
                         'crank_phase', 'publish_rate'}
    for name, spec in PARAMETERS.items():
        assert f'[{spec.unit}]' in descriptors[name].description or not spec.unit
        assert descriptors[name].additional_constraints.startswith('allowed: ')
    offset_range = descriptors['coupling_offset'].floating_point_range[0]
    # 0.9 r1, shown as 0.0225 (not 0.022500000000000003) in descriptors and messages.
    assert (offset_range.from_value, offset_range.to_value) == (-0.0225, 0.0225)
    assert descriptors['frame_id'].type == ParameterType.PARAMETER_STRING
    defaults = {name: h.shaper.get_parameter(name).value for name in PARAMETERS}
    assert defaults == {name: spec.default for name, spec in PARAMETERS.items()}
    assert (defaults['coupling_radius'], defaults['crank_radius'],
            defaults['pivot_distance']) == (R1, R, H_PIVOT)


# name, value, words every reason must contain (besides the name and the value's repr).
REFUSALS = [
    ('coupling_offset', 0.03, ['[-0.0225, 0.0225] m', 'max_safe_offset']),
    ('coupling_offset', -0.0230, ['[-0.0225, 0.0225] m']),
    ('coupling_offset', 0.025, ['[-0.0225, 0.0225] m']),
    ('coupling_offset', math.nan, ['not finite', '[-0.0225, 0.0225] m']),
    ('coupling_offset', math.inf, ['not finite']),
    ('coupling_offset', 'abc', ['floating-point', '[-0.0225, 0.0225] m']),
    ('coupling_offset', True, ['floating-point']),
    ('coupling_offset', [0.01], ['floating-point']),
    ('offset_rate_limit', 0.0, ['[1e-06, 1] m/s']),
    ('offset_rate_limit', -0.001, ['[1e-06, 1] m/s']),
    ('input_acceleration_limit', 0.0, ['[0.001, 100000] rad/s^2']),
    ('input_acceleration_limit', -math.inf, ['not finite']),
    ('input_speed', 61.0, ['[-60, 60] rad/s', 'max_input_speed']),
    ('input_speed', -math.inf, ['not finite']),
    ('max_input_speed', 0.0, ['[0.001, 10000] rad/s']),
    ('max_input_speed', 5.0, ['below |input_speed| = 6.28319 rad/s']),
    ('publish_rate', 50.0, ['read-only', 'it stays 100.0']),
    ('crank_radius', 0.2, ['read-only', 'must be smaller than pivot_distance']),
    ('coupling_radius', 0.03, ['read-only']),
    ('frame_id', '', ['non-empty string']),
    ('frame_id', 3.0, ['non-empty string']),
]


@pytest.mark.parametrize('name, value, words', REFUSALS,
                         ids=[f'{n}={v!r}' for n, v, _ in REFUSALS])
def test_bad_values_are_refused_with_a_reason_and_change_nothing(harness, name, value, words):
    h = harness(spin_shaper=False)
    before = {n: h.shaper.get_parameter(n).value for n in PARAMETERS}
    commands = (h.shaper.stepper.speed_command, h.shaper.stepper.offset_command)
    result, = h.shaper.set_parameters([Parameter(name, value=value)])
    assert not result.successful
    assert result.reason.startswith(f'{name} = {value!r} refused: ')
    for word in words:
        assert word in result.reason
    assert {n: h.shaper.get_parameter(n).value for n in PARAMETERS} == before
    assert (h.shaper.stepper.speed_command, h.shaper.stepper.offset_command) == commands


def test_an_undeclared_name_is_refused_naming_it(harness):
    h = harness(spin_shaper=False)
    result, = h.shaper.set_parameters([Parameter('coupling_ofset', value=0.01)])
    assert not result.successful
    assert result.reason.startswith('coupling_ofset: no such parameter of shaper_sim')
    assert 'coupling_offset' in result.reason
    assert not h.shaper.has_parameter('coupling_ofset')


def test_the_on_set_callback_refuses_too(harness):
    # rclpy's own path (descriptor checks, then on-set callbacks) without this node's
    # front check: cross-parameter rules still refuse, with the same reason.
    h = harness(spin_shaper=False)
    result = Node.set_parameters_atomically(h.shaper, [Parameter('input_speed', value=70.0)])
    assert not result.successful and 'input_speed = 70.0 refused' in result.reason
    assert h.shaper.get_parameter('input_speed').value == 2 * math.pi


def test_accepted_values_reach_the_stepper(harness):
    h = harness(spin_shaper=False)
    results = h.shaper.set_parameters([
        Parameter('coupling_offset', value=0.0225), Parameter('input_speed', value=-3),
        Parameter('offset_rate_limit', value=0.01),
        Parameter('input_acceleration_limit', value=50.0),
        Parameter('frame_id', value='shaper_table')])
    assert all(r.successful for r in results), [r.reason for r in results]
    stepper = h.shaper.stepper
    assert (stepper.offset_command, stepper.speed_command) == (0.0225, -3.0)
    assert (stepper.offset_rate_limit, stepper.input_acceleration_limit) == (0.01, 50.0)
    # An integer for a double parameter is taken as that double (`ros2 param set ... 0`).
    assert h.shaper.get_parameter('input_speed').type_ == Parameter.Type.DOUBLE
    # Raising the limit and the speed together is one consistent change.
    result = h.shaper.set_parameters_atomically([Parameter('max_input_speed', value=100.0),
                                                 Parameter('input_speed', value=90.0)])
    assert result.successful, result.reason
    assert stepper.speed_command == 90.0


def test_a_consistent_atomic_change_is_judged_as_a_whole(harness):
    h = harness(spin_shaper=False, input_speed=50.0)
    # Lowering the limit below today's command is fine when the same change lowers the
    # command: the cross-check sees every value after the change.
    result = h.shaper.set_parameters_atomically([Parameter('input_speed', value=5.0),
                                                 Parameter('max_input_speed', value=10.0)])
    assert result.successful, result.reason
    assert h.shaper.stepper.speed_command == 5.0
    result = h.shaper.set_parameters_atomically([Parameter('max_input_speed', value=4.0),
                                                 Parameter('input_speed', value=4.5)])
    assert not result.successful and 'below |input_speed| = 4.5 rad/s' in result.reason


def test_the_rclpy_internals_this_node_relies_on_still_work(harness):
    # shaper_sim.py isolates three uses of rclpy internals; an rclpy update breaking one
    # must fail here, not in a user's hands.
    h = harness(spin_shaper=True, coupling_offset=0.004)
    # 1. The start-up overrides are where the node finds a refused or unknown value.
    assert h.shaper._start_up_overrides()['coupling_offset'].value == 0.004
    # 2. The parameter services' callbacks are replaced: a malformed type gets a reason.
    client = h.probe.create_client(SetParameters, '/shaper_sim/set_parameters')
    malformed = ParameterMsg(name='input_speed', value=ParameterValue(type=42))
    result, = call(client, SetParameters.Request(parameters=[malformed])).results
    assert not result.successful and 'input_speed: malformed request refused' in result.reason
    # 3. rclpy's own set path (pre-set callback) takes an integer for a double.
    assert Node.set_parameters_atomically(
        h.shaper, [Parameter('input_speed', value=3)]).successful
    assert h.shaper.get_parameter('input_speed').type_ == Parameter.Type.DOUBLE
    assert h.shaper.stepper.speed_command == 3.0


def test_bad_start_up_values_are_refused_with_a_reason(context):
    for overrides, words in [
            ({'coupling_offset': 0.024}, ['coupling_offset = 0.024 refused',
                                          '[-0.0225, 0.0225]']),
            ({'crank_radius': 0.12}, ['crank_radius', '0.12', 'pivot_distance']),
            ({'input_speed': 80.0}, ['input_speed = 80.0 refused', '[-60, 60]']),
            ({'offset_rate_limit': -1.0}, ['offset_rate_limit = -1.0 refused', '[1e-06, 1]']),
            ({'publish_rate': 100}, ['publish_rate = 100 refused', 'decimal point',
                                     'e.g. 100.0'])]:
        with pytest.raises(ValueError) as error:
            ShaperSimNode(context=context, parameter_overrides=[
                Parameter(name, value=value) for name, value in overrides.items()])
        for word in words:
            assert word in str(error.value)
        assert 'Invalid parameter' not in str(error.value)  # this node's words, not rclpy's


# Publishing and diagnostics ---------------------------------------------------------------

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
    publish_at, measure_steps = shaper.publish_at, shaper._monitor.measure_steps

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
    shaper._monitor.measure_steps = recorded_steps
    return steps_at


def test_a_stroke_pair_is_measured_a_step_at_a_time_between_ticks(harness):
    """Out of time after a tick, a pair waits; it still moves a step every other tick."""
    h = harness(spin_shaper=False)
    shaper = h.shaper
    shaper._pair_step_budget_ns = 0  # every tick out of time
    steps_at = _ticks_of_pair_steps(shaper)
    completed = []
    collect = shaper._monitor.collect

    def kept_collect(*sample):
        result = collect(*sample)
        if result is not None:
            completed.append(result)
        return result

    shaper._monitor.collect = kept_collect
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
    assert shaper._monitor.measure(completed[0]) == []
    for message, samples in zip(h.diagnostics, completed[1:]):
        whole, = shaper._monitor.measure(samples)
        values = pair_values(message)
        assert {name: values[name] for name in whole.measured} == whole.measured


def test_a_pair_within_the_budget_is_reported_by_the_tick_that_completed_it(harness):
    h = harness(spin_shaper=False)
    shaper = h.shaper
    shaper._pair_step_budget_ns = 10 ** 12
    steps_at = _ticks_of_pair_steps(shaper)
    # Samples completed at about 1 s (no whole pair) and 2 s (one): each measured at once.
    run_ticks(shaper, 5000 * NS, 2.5, wait_for_reports=False)
    assert shaper.pair_reports_published == 1 and len(set(steps_at)) == 2


def test_pairs_are_still_reported_while_paused(harness):
    h = harness(spin_shaper=False)
    shaper = h.shaper
    shaper._pair_step_budget_ns = 0
    run_ticks(shaper, 5000 * NS, 2.0, wait_for_reports=False)  # a pair completed at 1.94 s
    assert shaper.pair_reports_published == 0  # its steps wait, one every other tick
    shaper._on_pause(SetBool.Request(data=True), SetBool.Response())
    for _ in range(200):
        shaper._on_timer()
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


def test_published_state_is_the_core_closed_form_at_the_stamp(harness):
    h = harness(spin_shaper=False, coupling_offset=0.005)
    h.shaper.set_parameters([Parameter('coupling_offset', value=0.012),
                             Parameter('input_speed', value=9.0)])
    stamps = run_ticks(h.shaper, 77 * NS, 1.0)
    h.wait_for(lambda: len(h.joint_states) == len(stamps), what='every joint state')
    geometry = h.shaper.geometry
    for message, stamp in zip(h.joint_states, stamps):
        assert list(message.name) == list(JOINT_NAMES)
        assert stamp_ns(message) == stamp
        assert message.header.frame_id == 'shaper_base'
        angle, flywheel, lever, ram, offset = message.position
        speed, flywheel_speed, lever_speed, ram_velocity, offset_rate = message.velocity
        expected = state(geometry, offset, angle, speed, 0.0, offset_rate)
        assert -math.pi <= angle < math.pi and -math.pi <= flywheel < math.pi
        assert math.remainder(flywheel - expected.flywheel_angle, 2 * math.pi) == \
            pytest.approx(0.0, abs=1e-12)
        assert (lever, ram) == pytest.approx((expected.lever_angle, expected.ram_position),
                                             abs=1e-15)
        assert (flywheel_speed, lever_speed, ram_velocity) == pytest.approx(
            (expected.flywheel_speed, expected.lever_speed, expected.ram_velocity),
            rel=1e-12, abs=1e-15)


def test_time_going_back_is_survived(harness):
    h = harness(spin_shaper=False)
    run_ticks(h.shaper, 100 * NS, 0.5)
    held = h.shaper.stepper.input_angle
    assert h.shaper.publish_at(3 * NS)  # simulated clock restarted
    assert h.shaper.stepper.input_angle == held and h.shaper.stepper.time_resets == 1
    assert not h.shaper.publish_at(3 * NS)  # a repeated stamp is not republished
    assert not h.shaper.publish_at(0)  # simulated time not started yet


# Services, pause, topic command, simulated time ---------------------------------------------

def test_pause_holds_and_resume_continues_from_the_held_state(harness):
    h = harness()
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    h.wait_for(lambda: len(h.joint_states) >= 5, what='joint states')
    response = h.call(SetBool, '/shaper_sim/pause', SetBool.Request(data=True))
    assert response.success and response.message == 'paused'
    count = len(h.joint_states)
    held = h.shaper.stepper.input_angle
    drawn = len(arrays)
    time.sleep(0.2)  # would be 20 ticks
    assert len(h.joint_states) == count and h.shaper.stepper.input_angle == held
    # The held state is still drawn (for a viewer that starts during the pause).
    h.wait_for(lambda: len(arrays) >= drawn + 3, what='markers while paused')
    stamp = h.joint_states[-1].header.stamp
    assert all(array.markers[0].header.stamp == stamp for array in arrays[drawn + 1:])
    assert h.call(SetBool, '/shaper_sim/pause', SetBool.Request(data=False)).success
    h.wait_for(lambda: len(h.joint_states) > count + 2, what='joint states after resuming')
    resumed = h.joint_states[count]
    assert resumed.position[0] == held  # the pause's 0.2 s do not count


def test_reset_returns_to_the_parameters(harness):
    h = harness(coupling_offset=0.004)
    h.wait_for(lambda: len(h.joint_states) >= 3, what='joint states')
    h.shaper.set_parameters([Parameter('input_speed', value=3.0)])
    response = h.call(Trigger, '/shaper_sim/reset', Trigger.Request())
    assert response.success and 'input speed 3.0 rad/s' in response.message
    # The first sample after the reset has angle 0 at speed 3 (the start had 2 pi rad/s).
    h.wait_for(lambda: any(m.velocity[0] == 3.0 for m in h.joint_states),
               what='joint states after reset')
    first = next(m for m in h.joint_states if m.velocity[0] == 3.0)
    assert first.position[0] == 0.0 and first.position[4] == 0.004


def test_speed_command_topic_accepts_good_values_and_ignores_bad_ones(harness):
    h = harness(spin_shaper=True)
    publisher = h.probe.create_publisher(Float64, 'input_speed_cmd', 10)
    h.wait_for(lambda: publisher.get_subscription_count() > 0, what='subscriber')
    for bad in (math.nan, math.inf, -61.0):
        publisher.publish(Float64(data=bad))
    publisher.publish(Float64(data=-12.5))
    h.wait_for(lambda: h.shaper.stepper.speed_command == -12.5, what='speed command')
    for bad in (math.nan, 1e9):
        publisher.publish(Float64(data=bad))
    count = len(h.joint_states)
    h.wait_for(lambda: len(h.joint_states) > count + 3, what='more joint states')
    assert h.shaper.stepper.speed_command == -12.5
    # The limit may not drop below the command in force.
    result, = h.shaper.set_parameters([Parameter('max_input_speed', value=10.0)])
    assert not result.successful and 'speed command in force' in result.reason


def test_use_sim_time_stamps_follow_clock(harness):
    h = harness(use_sim_time=True)
    clock = h.probe.create_publisher(Clock, '/clock', 10)
    start = 1234 * NS
    published = []
    deadline = time.monotonic() + 10.0
    stamp = start
    while len(h.joint_states) < 20 and time.monotonic() < deadline:
        stamp += 10_000_000
        clock.publish(Clock(clock=rclpy.time.Time(nanoseconds=stamp).to_msg()))
        published.append(stamp)
        time.sleep(0.002)
    assert len(h.joint_states) >= 20, 'no joint states on simulated time'
    stamps = [stamp_ns(m) for m in h.joint_states]
    assert all(s in published for s in stamps)
    assert stamps == sorted(stamps)


# Markers ----------------------------------------------------------------------------------

def test_markers_show_the_published_state_and_clear_on_reset(harness):
    h = harness(spin_shaper=False, coupling_offset=0.012, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    assert not h.shaper.publish_markers()  # nothing published yet: nothing to draw
    run_ticks(h.shaper, 50 * NS, 0.37)
    assert h.shaper.publish_markers()
    h.wait_for(lambda: arrays and len(h.joint_states) >= 37, what='markers and joint states')
    joint_state = h.joint_states[-1]
    markers = {(m.ns, m.id): m for m in arrays[-1].markers}
    assert all(m.header.stamp == joint_state.header.stamp for m in markers.values())
    # The pins, from the published joint values by the mechanism's own definitions
    # (mechanism.md): coupling pin on the input crank at r1 about O1 = (0, offset); crank pin
    # on the flywheel at r, at the crank phase; ram block on the ram line, H above O3.
    angle, flywheel, lever, ram, offset = joint_state.position
    expected = [(R1 * math.cos(angle), offset + R1 * math.sin(angle)),
                (R * math.cos(flywheel), R * math.sin(flywheel)),
                (0.2 * math.tan(lever), -H_PIVOT + 0.2)]
    pins = markers['pins', 0].points
    for point, (x, y) in zip(pins, expected):
        assert (point.x, point.y) == pytest.approx((x, y), abs=1e-12)
    assert pins[2].x == pytest.approx(ram, abs=1e-15)
    assert 'offset +12.00 mm' in markers['label', 0].text
    # The service's callback, called as the executor would (this node is not spun here).
    assert h.shaper._on_reset(Trigger.Request(), Trigger.Response()).success
    count = len(arrays)
    run_ticks(h.shaper, 60 * NS, 0.05)
    assert h.shaper.publish_markers()
    h.wait_for(lambda: len(arrays) >= count + 2, what='markers after the reset')
    assert [m.action for m in arrays[count].markers] == [Marker.DELETEALL]
    assert len(arrays[count + 1].markers) > 5


def test_still_markers_go_out_when_they_change_and_every_refresh_period(harness, monkeypatch):
    h = harness(spin_shaper=False, coupling_offset=0.012, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    stamp = [50 * NS]

    def publish(count=1):
        for _ in range(count):
            stamp[0] = run_ticks(h.shaper, stamp[0], 0.02)[-1]
            assert h.shaper.publish_markers()
        h.wait_for(lambda: len(arrays) >= sent + count, what='markers')
        return [len(array.markers) for array in arrays[sent:sent + count]]

    sent = 0
    assert publish(3) == [len(MARKER_KEYS), len(MOVING_KEYS), len(MOVING_KEYS)]
    sent = len(arrays)
    h.shaper.stepper.set_offset_command(0.0)  # the offset jumps: pivots and label change
    h.shaper.stepper.set_limits(offset_rate_limit=1e9)
    assert publish(2) == [len(MARKER_KEYS), len(MOVING_KEYS)]
    sent = len(arrays)
    monkeypatch.setattr(shaper_sim, 'MARKER_REFRESH_PERIOD', 0.0)  # a late viewer's refresh
    assert publish(2) == [len(MARKER_KEYS), len(MARKER_KEYS)]


def test_markers_follow_ticks_at_their_rate_and_survive_the_clock_going_back(harness):
    h = harness(spin_shaper=False, marker_rate=30.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 1000)
    stamps = run_ticks(h.shaper, 50 * NS, 2.0, rate=1000.0, jitter_ns=100_000)
    h.wait_for(lambda: len(arrays) >= 60, what='two seconds of markers')
    marker_stamps = [stamp_ns(array.markers[0]) for array in arrays]
    assert set(marker_stamps) <= set(stamps)  # each drawn at a published sample
    # 30 Hz on average, each within a tick period (1 ms, jitter 0.1 ms) of its due time.
    assert len(marker_stamps) == 60
    for index, stamp in enumerate(marker_stamps):
        assert 0 <= stamp - (marker_stamps[0] + index * NS / 30) < 1.2e6
    run_ticks(h.shaper, 10 * NS, 0.2, rate=1000.0, jitter_ns=100_000)  # sim time restarted
    h.wait_for(lambda: len(arrays) >= 66, what='markers going on after the clock went back')


def test_above_the_slicing_rate_a_frame_goes_out_one_marker_a_tick(harness):
    """The same frames as in one array, each marker in a tick of its own after the build."""
    rate = 2 * shaper_sim.MARKER_SLICING_RATE
    h = harness(spin_shaper=False, publish_rate=rate, marker_rate=50.0, coupling_offset=0.012)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 1000)
    stamps = run_ticks(h.shaper, 50 * NS, 0.1, rate=rate, jitter_ns=0)
    h.wait_for(lambda: len(h.joint_states) == len(stamps), what='the joint states')
    assert h.shaper._on_reset(Trigger.Request(), Trigger.Response()).success
    stamps += run_ticks(h.shaper, 60 * NS, 0.02, rate=rate, jitter_ns=0)
    frames = len(MARKER_KEYS) + 4 * len(MOVING_KEYS) + 1 + len(MARKER_KEYS)
    h.wait_for(lambda: len(arrays) >= frames, what='five frames, one marker a message')
    assert all(len(array.markers) == 1 for array in arrays)
    markers = [array.markers[0] for array in arrays]
    # Grouped by the sample they draw: whole, four moving ones, then DELETEALL and whole.
    groups = [(stamp, list(group)) for stamp, group in itertools.groupby(markers, stamp_ns)]
    keys = [[(m.ns, m.id) for m in group if m.action != Marker.DELETEALL]
            for _, group in groups]
    assert keys[:6] == [list(MARKER_KEYS)] + [list(MOVING_KEYS)] * 4 + [list(MARKER_KEYS)]
    assert [m.action for m in groups[5][1]][0] == Marker.DELETEALL
    # Every marker as the unsliced frame at that sample has it (the published input angle).
    states = {stamp_ns(m): m for m in h.joint_states}
    for (stamp, group), moving in zip(groups[:5], [False] + [True] * 4):
        angle = states[stamp].position[0]
        expected = linkage_marker_array(h.shaper.geometry, 0.012, angle, stamp,
                                        h.shaper.get_parameter('frame_id').value,
                                        input_speed=2 * math.pi, loads=h.shaper._loads,
                                        moving_only=moving).markers
        # (as received: the colours' float32 on the wire)
        assert group == [deserialize_message(serialize_message(m), Marker) for m in expected]
    # Each marker a tick after the one before; the frames 1/50 s apart from the first.
    ticks = [stamps.index(stamp) for stamp, _ in groups]
    assert [b - a for a, b in zip(ticks, ticks[1:4])] == [int(rate / 50)] * 3
    # A reset in the middle of a frame drops its rest: the next message is the DELETEALL.
    h.wait_for(lambda: len(arrays) == frames, what='no more markers')
    run_ticks(h.shaper, 70 * NS, 2 / rate, rate=rate, jitter_ns=0)  # a frame, one marker out
    assert h.shaper._on_reset(Trigger.Request(), Trigger.Response()).success
    run_ticks(h.shaper, 71 * NS, 3 / rate, rate=rate, jitter_ns=0)
    h.wait_for(lambda: len(arrays) >= frames + 3, what='a marker, then the next frame')
    assert [m.action for array in arrays[frames:frames + 3] for m in array.markers] == [
        Marker.ADD, Marker.DELETEALL, Marker.ADD]


def test_markers_show_the_workpiece_while_there_is_a_cutting_load(harness):
    h = harness(spin_shaper=False, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    run_ticks(h.shaper, 50 * NS, 0.05)
    assert h.shaper.publish_markers()
    assert h.shaper.set_parameters([Parameter('cutting_force', value=400.0),
                                    Parameter('cutting_length', value=0.15)])[0].successful
    run_ticks(h.shaper, 51 * NS, 0.05)
    assert h.shaper.publish_markers()  # the loads changed: the whole array, workpiece drawn
    h.wait_for(lambda: len(arrays) >= 2, what='markers before and after the load')
    before, after = ({(m.ns, m.id): m for m in array.markers} for array in arrays[:2])
    assert before['workpiece', 0].action == Marker.DELETE
    assert after['workpiece', 0].action == Marker.ADD
    # The tool tip's range while cutting: cutting_length long (linkage.workpiece_span).
    assert after['workpiece', 0].scale.x == pytest.approx(0.15, rel=1e-12)


def test_marker_rate_is_live_and_zero_turns_markers_off(harness):
    h = harness(marker_rate=50.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    h.wait_for(lambda: len(arrays) >= 5, what='markers at 50 Hz')
    assert h.shaper.set_parameters([Parameter('marker_rate', value=0.0)])[0].successful
    result, = h.shaper.set_parameters([Parameter('marker_rate', value=-1.0)])
    assert not result.successful and '[0, 1000] Hz' in result.reason
    time.sleep(0.1)  # let markers already under way arrive
    count = len(arrays)
    time.sleep(0.3)  # 15 periods at the old rate: none may come
    assert len(arrays) == count


# Efforts ----------------------------------------------------------------------------------

def test_published_efforts_balance_the_energy(harness):
    # Power in at the input shaft = d(kinetic + potential energy)/dt - (load force x ram
    # velocity), with every term from the published joint values and the mass parameters
    # (doc/dynamics.md), the derivative by central differences at 10 kHz.
    mass = dict(input_inertia=0.01, flywheel_inertia=0.5, lever_inertia=0.3, lever_mass=8.0,
                lever_com_distance=0.15, ram_mass=20.0, gravity=9.81)
    h = harness(spin_shaper=False, coupling_offset=0.01, input_speed=4.0, cutting_force=500.0,
                ram_friction=30.0, cutting_length=0.15, **mass)
    rate = 10000.0
    stamps = [5 * NS + i * 100_000 for i in range(1, int(1.3 * rate))]
    for index, stamp in enumerate(stamps, 1):
        assert h.shaper.publish_at(stamp)
        if index % 500 == 0 or index == len(stamps):  # within the probe's queue
            h.wait_for(lambda: len(h.joint_states) == index, what='every joint state')

    def energy(message):
        angle, flywheel, lever, ram, offset = message.position
        speed, flywheel_speed, lever_speed, ram_velocity, _ = message.velocity
        kinetic = 0.5 * (mass['input_inertia'] * speed ** 2
                         + mass['flywheel_inertia'] * flywheel_speed ** 2
                         + mass['lever_inertia'] * lever_speed ** 2
                         + mass['ram_mass'] * ram_velocity ** 2)
        return kinetic + mass['lever_mass'] * mass['gravity'] * mass['lever_com_distance'] * \
            math.cos(lever)

    def load(message):
        ram, velocity = message.position[3], message.velocity[3]
        cutting = 500.0 if velocity < 0.0 and abs(ram) <= 0.075 else 0.0
        return cutting - math.copysign(30.0, velocity)

    checked = 0
    for before, middle, after in zip(h.joint_states, h.joint_states[1:], h.joint_states[2:]):
        assert len(middle.effort) == 5 and all(map(math.isfinite, middle.effort))
        if len({load(before), load(middle), load(after)}) > 1:
            continue  # a load switch between the samples: no smooth derivative there
        energy_rate = (energy(after) - energy(before)) * rate / 2
        power_in = middle.effort[0] * middle.velocity[0]
        load_power = load(middle) * middle.velocity[3]
        assert power_in == pytest.approx(energy_rate - load_power,
                                         abs=1e-4 * (1.0 + abs(power_in))), middle
        checked += 1
    assert checked > 0.95 * len(stamps)


def test_one_sample_efforts_equal_the_vectorised_ones():
    # The node's per-tick path (floats, math functions) and the array path agree.
    from qrm_ros.core.dynamics import efforts, MassProperties
    from qrm_ros.core.geometry import Geometry
    import numpy as np
    geometry, mass = Geometry.paper(), MassProperties.small_shaper()
    angles = np.linspace(-3.0, 3.0, 13)
    vectorised = efforts(geometry, mass, 0.013, angles, 5.0, 2.0, 0.004, 0.0, 300.0)
    for index, angle in enumerate(angles):
        one = efforts(geometry, mass, 0.013, float(angle), 5.0, 2.0, 0.004, 0.0, 300.0)
        assert one == pytest.approx([v[index] for v in vectorised], rel=1e-13, abs=1e-12)
