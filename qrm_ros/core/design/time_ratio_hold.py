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
Holding a time ratio with the offset as the stroke changes (the paper's short strokes), no ROS.

On a short stroke a plain quick-return mechanism loses its quick return (r/h small, TR near
1); a positive offset gives it back. The node asks, whenever the target or the stroke
changes, which offset gives the target time ratio (forward running) at the crank radius of
the stroke: the exact inverse, offset_for_time_ratio, within the offset's safety limit. A
target outside what the safe offsets reach is refused when it is set; if a later stroke
change puts it out of reach, the nearest reachable offset is held and the answer says so.
"""

from typing import Optional, Tuple

import numpy as np

from qrm_ros.core.design.cutting_speed_hold import HoldAnswer, exact_or_nearest_offset
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics.offset_inverses import offset_for_time_ratio
from qrm_ros.core.kinematics.stroke_timing import time_ratio

__all__ = ['hold_time_ratio', 'reachable_time_ratios', 'time_ratio_unreachable_reason']

_RANGE_SAMPLES = 201  # offsets tried across the safe range (ends included)


def _over_safe_offsets(geometry: Geometry) -> Tuple[np.ndarray, np.ndarray]:
    limit = geometry.max_safe_offset
    offsets = np.linspace(-limit, limit, _RANGE_SAMPLES)
    return offsets, np.asarray(time_ratio(geometry, offsets))


def reachable_time_ratios(geometry: Geometry) -> Tuple[float, float]:
    """(lowest, highest) forward time ratio the safe offsets give at this crank radius."""
    _, ratios = _over_safe_offsets(geometry)
    return float(ratios.min()), float(ratios.max())


def time_ratio_unreachable_reason(geometry: Geometry, target: float,
                                  reachable: Optional[Tuple[float, float]] = None
                                  ) -> Optional[str]:
    """Say why no safe offset gives the target time ratio, or return None if one does."""
    low, high = reachable or reachable_time_ratios(geometry)
    if low <= target <= high:
        return None
    return (f'time ratio {target:.6g} is out of reach at stroke {geometry.ram_stroke:.6g} m '
            f'(crank radius {geometry.crank_radius:.6g} m): offsets within the safety limit '
            f'(|offset| <= {geometry.max_safe_offset:.6g} m) give {low:.6g} to {high:.6g}')


def hold_time_ratio(geometry: Geometry, target: float) -> HoldAnswer:
    """Return the offset giving the target time ratio at this crank radius, or the nearest."""
    offsets, ratios = _over_safe_offsets(geometry)
    reachable = float(ratios.min()), float(ratios.max())
    return exact_or_nearest_offset(
        geometry, target, offsets, ratios,
        time_ratio_unreachable_reason(geometry, target, reachable),
        lambda: offset_for_time_ratio(geometry, target),
        f'time ratio {target:.6g}', lambda ratio: f'time ratio {ratio:.6g}')
