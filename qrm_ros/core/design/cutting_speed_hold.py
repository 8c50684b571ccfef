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
Holding a cutting speed with the offset (the paper's "precise adjustment of speed"), no ROS.

The node asks, whenever the target, its definition or the speed command changes, which
offset gives the target at that speed within the offset's safety limit. A target outside
what the safe offsets reach is refused when it is set; if a later speed change puts it out of
reach, the nearest reachable offset is held and the answer says so.
"""

from typing import Callable, NamedTuple, Optional, Tuple

import numpy as np

from qrm_ros.core.common.checks import KinematicsError
from qrm_ros.core.kinematics.cutting_speeds import (mean_cutting_speed,
                                                    offset_for_mean_cutting_speed)
from qrm_ros.core.kinematics.geometry import ArrayLike, FloatOrArray, Geometry
from qrm_ros.core.kinematics.offset_inverses import offset_for_cutting_speed
from qrm_ros.core.kinematics.peak_speeds import peak_ram_speeds

__all__ = ['CUTTING_SPEED_DEFINITIONS', 'CUTTING_SPEED_FIGURES', 'HoldAnswer', 'cutting_speed',
           'exact_or_nearest_offset', 'hold_offset', 'unreachable_reason',
           'reachable_cutting_speeds']

# 'mean': stroke length / cutting time, the figure of shop tables; 'peak': the largest
# cutting speed in the stroke.
CUTTING_SPEED_DEFINITIONS = ('mean', 'peak')
# The stroke-pair measurement (qrm_ros.core.measurement.strokes.StrokePairs) of each definition.
CUTTING_SPEED_FIGURES = {'mean': 'mean_cutting_speed', 'peak': 'peak_cutting_speed'}
# Offsets tried across the safe range to find what it reaches (ends included).
_RANGE_SAMPLES = 201


def cutting_speed(geometry: Geometry, offset: ArrayLike, input_speed: ArrayLike,
                  definition: str) -> FloatOrArray:
    """Cutting speed (m/s, >= 0) at an offset and input speed, by its definition."""
    if definition == 'mean':
        return mean_cutting_speed(geometry, offset, input_speed)
    if definition == 'peak':
        return peak_ram_speeds(geometry, offset, input_speed)[0]
    raise KinematicsError(f'cutting speed definition {definition!r} is not one of '
                          f'{", ".join(CUTTING_SPEED_DEFINITIONS)}')


def _over_safe_offsets(geometry, input_speed, definition):
    """(offsets, cutting speeds) across the safe offset range, ends included."""
    limit = geometry.max_safe_offset
    offsets = np.linspace(-limit, limit, _RANGE_SAMPLES)
    return offsets, np.asarray(cutting_speed(geometry, offsets, input_speed, definition))


def reachable_cutting_speeds(geometry: Geometry, input_speed: float,
                             definition: str) -> Tuple[float, float]:
    """(lowest, highest) cutting speed the safe offsets give at input_speed (m/s)."""
    _, speeds = _over_safe_offsets(geometry, input_speed, definition)
    return float(speeds.min()), float(speeds.max())


def unreachable_reason(geometry: Geometry, input_speed: float, target: float,
                       definition: str,
                       reachable: Optional[Tuple[float, float]] = None) -> Optional[str]:
    """
    Say why no safe offset gives the target at input_speed, or return None if one does.

    The node's refusal of a target and its warning when it holds the nearest offset both say
    this, in these words. reachable: the range if already known.
    """
    if input_speed == 0.0:
        return 'the input speed command is 0 rad/s: no offset gives a cutting speed'
    low, high = reachable or reachable_cutting_speeds(geometry, input_speed, definition)
    if low <= target <= high:
        return None
    return (f'{definition} cutting speed {target:.6g} m/s is out of reach at the input speed '
            f'command {input_speed:.6g} rad/s: offsets within the safety limit (|offset| <= '
            f'{geometry.max_safe_offset:.6g} m) give {low:.6g} to {high:.6g} m/s')


class HoldAnswer(NamedTuple):
    """The offset to command, and why it is not exact when it is not."""

    offset: float                # m, within the safety limit
    reachable: Tuple[float, float]  # the held figure's range (m/s, or a time ratio)
    problem: Optional[str]       # None: the offset gives the target exactly


def hold_offset(geometry: Geometry, input_speed: float, target: float,
                definition: str) -> HoldAnswer:
    """Return the offset giving the target cutting speed at input_speed, or the nearest."""
    if input_speed == 0.0:
        reason = unreachable_reason(geometry, input_speed, target, definition)
        return HoldAnswer(0.0, (0.0, 0.0), f'{reason}; offset 0 m held')
    offsets, speeds = _over_safe_offsets(geometry, input_speed, definition)
    reachable = float(speeds.min()), float(speeds.max())
    invert = (offset_for_mean_cutting_speed if definition == 'mean'
              else offset_for_cutting_speed)
    return exact_or_nearest_offset(
        geometry, target, offsets, speeds,
        unreachable_reason(geometry, input_speed, target, definition, reachable),
        lambda: invert(geometry, input_speed, target),
        f'{definition} cutting speed {target:.6g} m/s', lambda speed: f'{speed:.6g} m/s')


def exact_or_nearest_offset(geometry: Geometry, target: float, offsets: np.ndarray,
                            figures: np.ndarray, reason: Optional[str],
                            exact_offset: Callable[[], FloatOrArray], target_text: str,
                            figure_text: Callable[[float], str]) -> HoldAnswer:
    """
    Answer a hold: the exact inverse's offset if the target is reachable and it is safe.

    Otherwise the sampled safe offset whose figure lies nearest the target, with the reason
    (the time-ratio hold and the cutting-speed hold share this rule).
    """
    reachable = float(figures.min()), float(figures.max())
    if reason is None:
        offset = float(exact_offset())
        if abs(offset) <= geometry.max_safe_offset:
            return HoldAnswer(offset, reachable, None)
        reason = (f'{target_text} needs offset {offset:.6g} m, '
                  f'beyond the safety limit {geometry.max_safe_offset:.6g} m')
    nearest = int(np.argmin(np.abs(figures - target)))
    return HoldAnswer(
        float(offsets[nearest]), reachable,
        f'{reason}; holding the nearest, offset {float(offsets[nearest]):.6g} m '
        f'({figure_text(float(figures[nearest]))})')
