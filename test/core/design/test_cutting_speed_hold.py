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
Holding a cutting speed with the offset: the ROS-free answer, and the node over real DDS
(the cutting speed measured from the published stroke pairs, not taken from the node).
"""

import math

import numpy as np
import pytest
from qrm_ros.core import kinematics as kin
from qrm_ros.core.design.cutting_speed_hold import (cutting_speed, hold_offset,
                                                    reachable_cutting_speeds)
from qrm_ros.core.common.names import CUTTING_SPEED_STATUS, STROKE_PAIR_STATUS
from rclpy.parameter import Parameter
from std_msgs.msg import Float64

from shaper_harness import NS, pair_values, run_ticks

PAPER = kin.Geometry.paper()
SPEED = 2.0 * math.pi
# Measured from 100 Hz samples the mean cutting speed is good to ~3e-4 (the cutting time's
# (w dt)^3); the issue asks for 1e-3.
SETTLED = 1e-3


@pytest.mark.parametrize('definition', ['mean', 'peak'])
@pytest.mark.parametrize('speed', [SPEED, 3.5, -SPEED])
def test_the_held_offset_gives_the_target(definition, speed):
    low, high = reachable_cutting_speeds(PAPER, speed, definition)
    for target in np.linspace(low, high, 7):
        answer = hold_offset(PAPER, speed, float(target), definition)
        assert answer.problem is None
        assert abs(answer.offset) <= PAPER.max_safe_offset
        assert cutting_speed(PAPER, answer.offset, speed, definition) == pytest.approx(
            target, rel=1e-12)


def test_reachable_range_is_the_safe_offsets_ends_and_beyond_it_the_nearest_is_held():
    limit = PAPER.max_safe_offset
    ends = sorted(cutting_speed(PAPER, np.array([-limit, limit]), SPEED, 'mean'))
    assert reachable_cutting_speeds(PAPER, SPEED, 'mean') == pytest.approx(ends, rel=1e-12)
    too_fast = hold_offset(PAPER, SPEED, 2.0 * ends[1], 'mean')
    assert 'out of reach' in too_fast.problem and f'{ends[1]:.6g}' in too_fast.problem
    assert cutting_speed(PAPER, too_fast.offset, SPEED, 'mean') == pytest.approx(ends[1])
    stopped = hold_offset(PAPER, 0.0, 0.3, 'mean')
    assert stopped.problem and '0 rad/s' in stopped.problem


# The node ---------------------------------------------------------------------------------

def target_in_reach(speed, definition='mean', where=0.3):
    low, high = reachable_cutting_speeds(PAPER, speed, definition)
    return low + where * (high - low)


def test_unreachable_targets_and_offsets_by_hand_are_refused_with_reasons(harness):
    h = harness(spin_shaper=False)
    low, high = reachable_cutting_speeds(PAPER, SPEED, 'mean')
    result, = h.shaper.set_parameters([Parameter('cutting_speed_target', value=high * 1.5)])
    assert not result.successful
    assert 'out of reach' in result.reason and f'{high:.6g}' in result.reason
    assert h.shaper.get_parameter('cutting_speed_target').value == 0.0
    target = target_in_reach(SPEED)
    assert h.shaper.set_parameters([Parameter('cutting_speed_target', value=target)])[0].successful
    result, = h.shaper.set_parameters([Parameter('coupling_offset', value=0.001)])
    assert not result.successful and 'set cutting_speed_target to 0' in result.reason
    result, = h.shaper.set_parameters([Parameter('cutting_speed_definition', value='fastest')])
    assert not result.successful and "'mean', 'peak'" in result.reason
    # Both in one atomic call: back to the offset by hand.
    assert h.shaper.set_parameters_atomically([
        Parameter('cutting_speed_target', value=0.0),
        Parameter('coupling_offset', value=0.001)]).successful
    assert h.shaper.stepper.offset_command == 0.001


def steady_cutting_speeds(diagnostics, since):
    """(target, measured) of the steady stroke pairs that ended after `since` (s)."""
    found = []
    for message in diagnostics:
        if message.status[0].name != STROKE_PAIR_STATUS:
            continue
        values = pair_values(message)
        if values['pair_start'] > since and values['offset_steady'] == 'true' and \
                values['input_speed_steady'] == 'true':
            found.append((values['cutting_speed_target'], values['cutting_speed_measured']))
    return found


@pytest.mark.parametrize('definition', ['mean', 'peak'])
def test_the_node_settles_on_the_target_and_follows_a_speed_change(harness, definition):
    h = harness(spin_shaper=False, offset_rate_limit=0.05, input_acceleration_limit=50.0)
    target = target_in_reach(SPEED, definition, 0.4)
    assert h.shaper.set_parameters([
        Parameter('cutting_speed_definition', value=definition),
        Parameter('cutting_speed_target', value=target)])[1].successful
    stamps = run_ticks(h.shaper, 5 * NS, 4.0)
    # A faster speed command: the node moves the offset to keep the same cutting speed.
    assert h.shaper.set_parameters([Parameter('input_speed', value=1.2 * SPEED)])[0].successful
    changed_at = stamps[-1] / NS
    run_ticks(h.shaper, stamps[-1], 4.0)
    h.wait_for(lambda: len(steady_cutting_speeds(h.diagnostics, changed_at)) >= 2,
               what='steady stroke pairs after the speed change')
    for since in (5.0, changed_at):
        pairs = steady_cutting_speeds(h.diagnostics, since)[-2:]
        assert pairs, since
        for held, measured in pairs:
            assert held == target
            assert measured == pytest.approx(target, rel=SETTLED)
    holds = [m for m in h.diagnostics if m.status[0].name == CUTTING_SPEED_STATUS]
    assert holds and all(m.status[0].level == b'\x00' for m in holds)


def test_a_speed_command_that_puts_the_target_out_of_reach_holds_the_nearest(harness):
    h = harness(spin_shaper=True)
    target = target_in_reach(SPEED, 'mean', 0.9)
    assert h.shaper.set_parameters([Parameter('cutting_speed_target',
                                              value=target)])[0].successful
    publisher = h.probe.create_publisher(Float64, 'input_speed_cmd', 10)
    h.wait_for(lambda: publisher.get_subscription_count() > 0, what='the node subscribed')
    publisher.publish(Float64(data=0.5 * SPEED))  # too slow for that cutting speed

    def warned():
        return [m for m in h.diagnostics if m.status[0].name == CUTTING_SPEED_STATUS
                and m.status[0].level == b'\x01']
    h.wait_for(warned, what='a WARN from the cutting-speed hold')
    status = warned()[-1].status[0]
    assert 'out of reach' in status.message
    limit = PAPER.max_safe_offset
    assert abs(h.shaper.stepper.offset_command) == pytest.approx(limit)
