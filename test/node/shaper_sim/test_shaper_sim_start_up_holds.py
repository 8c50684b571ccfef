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
"""A hold given at start-up: shaper_sim runs and commands the offset from its first tick.

A hold set at start-up beside the default coupling_offset once refused to start (the rule
that keeps a hand-set offset from fighting a hold judged the start-up value as a change).
"""

import math

import pytest
from qrm_ros.core.design.cutting_speed_hold import hold_offset
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import PUBLISHED_JOINT_NAMES
from qrm_ros.core.kinematics.offset_inverses import offset_for_time_ratio
from rclpy.parameter import Parameter

from shaper_harness import NS
from test_shaper_sim_stroke import publish_for, steady_pairs

OFFSET = PUBLISHED_JOINT_NAMES.index('coupling_offset_joint')


def test_time_ratio_hold_at_start_up_commands_the_offset_and_is_measured(harness):
    h = harness(spin_shaper=False, time_ratio_target=1.9, offset_rate_limit=0.02)
    expected = float(offset_for_time_ratio(Geometry.paper(), 1.9))
    assert h.shaper.stepper.offset_command == pytest.approx(expected, rel=1e-12)
    mark = len(h.diagnostics)
    publish_for(h, 5 * NS, 4.0)
    pairs = steady_pairs(h, mark)
    assert len(pairs) >= 2
    for pair in pairs:  # measured from the published samples
        assert abs(pair['time_ratio'] / 1.9 - 1.0) < 1e-3, pair


def test_cutting_speed_hold_at_start_up_commands_the_offset(harness):
    h = harness(spin_shaper=False, cutting_speed_target=0.25)
    expected = hold_offset(Geometry.paper(), 2 * math.pi, 0.25, 'mean').offset
    assert h.shaper.stepper.offset_command == pytest.approx(expected, rel=1e-12)


def test_a_start_up_offset_beside_a_hold_is_where_the_offset_starts(harness):
    h = harness(spin_shaper=False, coupling_offset=0.01, time_ratio_target=1.9,
                offset_rate_limit=0.005)
    publish_for(h, 5 * NS, 0.2)
    first, last = h.joint_states[0], h.joint_states[-1]
    target = float(offset_for_time_ratio(Geometry.paper(), 1.9))
    assert first.position[OFFSET] == pytest.approx(0.01, abs=0.005 * 0.001 * 1.01)
    assert abs(last.position[OFFSET] - target) < abs(first.position[OFFSET] - target)
    # Live, the hand-set offset still yields to the hold, with the reason.
    result, = h.shaper.set_parameters([Parameter('coupling_offset', value=0.0)])
    assert not result.successful
    assert 'commanded by time_ratio_target = 1.9' in result.reason


def test_both_holds_at_start_up_are_refused_with_the_reason(harness):
    with pytest.raises(ValueError, match='both command the offset'):
        harness(spin_shaper=False, time_ratio_target=1.9, cutting_speed_target=0.25)
