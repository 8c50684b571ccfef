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
A value moved toward its target at a rate limit, integrated exactly (stepping's ramps).

The input speed, the offset and the ram stroke each follow their command this way; the
profile is piecewise linear in time, so a step's integral is its trapezoid.
"""

import math
from typing import Tuple

__all__ = ['ramp']


def ramp(value: float, target: float, rate_limit: float,
         duration: float) -> Tuple[float, float]:
    """
    Move value toward target at rate_limit for duration seconds.

    Returns (value at the end, exact integral of the value over the interval).
    """
    gap = target - value
    reach = rate_limit * duration
    if abs(gap) <= reach:
        # The ramp reaches the target inside the interval and holds it afterwards.
        reach_time = abs(gap) / rate_limit
        return target, 0.5 * (value + target) * reach_time + target * (duration - reach_time)
    end = value + math.copysign(reach, gap)
    if (target - end) * gap <= 0.0:
        end = target  # rounding carried the value onto or past the target
    return end, 0.5 * (value + end) * duration
