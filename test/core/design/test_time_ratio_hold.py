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
The time-ratio hold: the offset that gives a time ratio at a stroke, or the nearest one.

Independent routes: the held offset's time ratio by RK4 of the paper's eq. (20) (it never
inverts the coupling); the reachable range against the ratios at the safe offsets' ends
(the ratio is monotonic in the offset there) by RK4 too; the unreachable paths' answers.
"""

import dataclasses

import numpy as np
import pytest

from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke, Geometry
from qrm_ros.core.kinematics.stroke_timing import time_ratio_rk4
from qrm_ros.core.design.time_ratio_hold import (hold_time_ratio, reachable_time_ratios,
                                                 time_ratio_unreachable_reason)

PAPER = Geometry.paper()


def at_stroke(stroke):
    return dataclasses.replace(PAPER, crank_radius=crank_radius_for_stroke(stroke, 0.113, 0.2))


@pytest.mark.parametrize('stroke, target', [(0.19983, 1.8), (0.06, 1.8), (0.06, 1.3),
                                            (0.3, 2.5), (0.1, 0.9)])
def test_the_held_offset_gives_the_target_time_ratio(stroke, target):
    geometry = at_stroke(stroke)
    answer = hold_time_ratio(geometry, target)
    assert answer.problem is None
    assert abs(answer.offset) <= geometry.max_safe_offset
    assert time_ratio_rk4(geometry, answer.offset) == pytest.approx(target, rel=1e-7)


@pytest.mark.parametrize('stroke', [0.06, 0.19983, 0.3])
def test_the_reachable_range_is_the_safe_offsets_ends(stroke):
    geometry = at_stroke(stroke)
    limit = geometry.max_safe_offset
    low, high = reachable_time_ratios(geometry)
    ends = sorted(time_ratio_rk4(geometry, offset) for offset in (-limit, limit))
    assert (low, high) == pytest.approx(ends, rel=1e-7)
    # Monotonic between the ends: the sampled range is the whole reachable range.
    inside = [time_ratio_rk4(geometry, offset) for offset in np.linspace(-limit, limit, 9)]
    assert np.all(np.diff(inside) > 0.0)


def test_out_of_reach_holds_the_nearest_safe_offset_and_says_why():
    long, short = at_stroke(0.19983), at_stroke(0.06)
    assert time_ratio_unreachable_reason(long, 10.0) is None  # reachable at the long stroke
    reason = time_ratio_unreachable_reason(short, 10.0)
    low, high = reachable_time_ratios(short)
    assert reason == (f'time ratio 10 is out of reach at stroke {short.ram_stroke:.6g} m '
                      f'(crank radius {short.crank_radius:.6g} m): offsets within the safety '
                      f'limit (|offset| <= {short.max_safe_offset:.6g} m) give {low:.6g} to '
                      f'{high:.6g}')
    above = hold_time_ratio(short, 10.0)
    assert above.problem.startswith(reason) and 'nearest' in above.problem
    assert above.offset == pytest.approx(short.max_safe_offset, rel=1e-12)
    assert above.reachable == (low, high)
    below = hold_time_ratio(short, 0.01)
    assert below.problem is not None
    assert below.offset == pytest.approx(-short.max_safe_offset, rel=1e-12)
