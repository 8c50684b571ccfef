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
The rules of the stroke parameters (stroke_length, max_crank_radius, the time-ratio hold).

Used by shaper_parameters' table; they look at a View (values after the change, the
start-up geometry, the stroke in force) and say why a value is refused, or None.
stroke_length 0 means the stroke of crank_radius (the start-up stroke), so crank_radius
stays the one start-up value and stroke_length the one live command.
"""

import dataclasses
import math
from typing import Any, NamedTuple, Optional, Tuple

from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke, Geometry, KinematicsError
from qrm_ros.core.stepping.stroke_adjustment import largest_stroke
from qrm_ros.core.design.time_ratio_hold import time_ratio_unreachable_reason

__all__ = ['StrokeLengthRange', 'commanded_geometry', 'commanded_stroke',
           'one_hold_at_a_time', 'slot_holds_crank', 'stroke_holds_workpiece',
           'time_ratio_reachable']


def _shown(value: float) -> str:
    return f'{value:.6g}'


def commanded_stroke(view: Any) -> float:
    """Return the stroke commanded (m): stroke_length, or crank_radius's when it is 0."""
    stroke = view.values.get('stroke_length', 0.0)
    return float(stroke) if stroke else float(view.geometry.ram_stroke)


def commanded_geometry(view: Any) -> Geometry:
    """Return the start-up geometry with the crank radius of the commanded stroke."""
    geometry = view.geometry
    stroke = view.values.get('stroke_length', 0.0)
    if not stroke:
        return geometry
    radius = float(crank_radius_for_stroke(stroke, geometry.pivot_distance,
                                           geometry.ram_height))
    return dataclasses.replace(geometry, crank_radius=radius)


class StrokeLengthRange(NamedTuple):
    """
    0 (the stroke of crank_radius) or a stroke whose crank radius fits the slot.

    The descriptor publishes [0, the slot's largest stroke]: 0 lies in it, and the slot
    (max_crank_radius) is read-only, so the range holds for the node's life.
    """

    def descriptor_bounds(self, geometry: Geometry,
                          view: Any = None) -> Optional[Tuple[float, float]]:
        if view is None:
            return None
        try:
            return 0.0, largest_stroke(geometry, view.values['max_crank_radius'])
        except KinematicsError:  # a slot the geometry refuses (its own refusal says why)
            return None

    def allowed(self, unit: str, view: Any) -> str:
        radius = view.values['max_crank_radius']
        try:
            limit = largest_stroke(view.geometry, radius)
        except KinematicsError:  # a slot the geometry refuses (its own refusal says why)
            limit = math.inf
        return (f'0 (the stroke of crank_radius) or 0 < stroke_length <= {_shown(limit)} '
                f'{unit} (crank radius up to max_crank_radius = {_shown(radius)} m)')

    def problem(self, value: Any, unit: str, view: Any) -> Optional[str]:
        allowed = self.allowed(unit, view)
        if not isinstance(value, float):
            return f'must be a floating-point number: {allowed}'
        if not math.isfinite(value):
            return f'not finite; allowed {allowed}'
        if value == 0.0:
            return None
        if value < 0.0 or value > largest_stroke(view.geometry,
                                                 view.values['max_crank_radius']):
            return f'outside the allowed range {allowed}'
        return None


def slot_holds_crank(value: float, view: Any) -> Optional[str]:
    """max_crank_radius: at least crank_radius, below pivot_distance."""
    geometry = view.geometry
    if value >= geometry.pivot_distance:
        return (f'not below pivot_distance = {_shown(geometry.pivot_distance)} m (the lever '
                'would turn fully round)')
    if value < geometry.crank_radius:
        return f'below crank_radius = {_shown(geometry.crank_radius)} m (the start-up radius)'
    return None


def stroke_holds_workpiece(value: float, view: Any) -> Optional[str]:
    """stroke_length: not shorter than the workpiece (cutting_length)."""
    length = view.values['cutting_length']
    if commanded_stroke(view) < length:
        return (f'shorter than cutting_length = {_shown(length)} m; shorten cutting_length '
                'first (or set both in one atomic call)')
    return None


def time_ratio_reachable(value: float, view: Any) -> Optional[str]:
    """time_ratio_target: a ratio the safe offsets give at the commanded stroke."""
    target = view.values['time_ratio_target']
    if target == 0.0:
        return None
    return time_ratio_unreachable_reason(commanded_geometry(view), target)


def one_hold_at_a_time(value: float, view: Any) -> Optional[str]:
    """time_ratio_target and cutting_speed_target: at most one commands the offset."""
    if view.values['time_ratio_target'] and view.values['cutting_speed_target']:
        return ('time_ratio_target and cutting_speed_target both command the offset: set the '
                'other to 0 first (or in the same atomic call)')
    return None
