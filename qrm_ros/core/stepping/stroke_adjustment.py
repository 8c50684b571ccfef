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
The stroke adjustment: the crank pin moved along the crank by the stroke screw.

A shaper's operator sets the ram stroke to the workpiece; the screw moves the crank pin
along the bull gear's slot, so the crank radius r is the state that moves. Its command is a
stroke S: the radius that gives it is r = S h / sqrt(4 H^2 + S^2)
(geometry.crank_radius_for_stroke). The stroke moves toward its command at a rate limit
(m/s of stroke, constant while it moves), so r(t) is smooth between the ramp's ends, with

    r' = dr/dS S',   r'' = d2r/dS2 S'^2,   dr/dS = 4 H^2 h / (4 H^2 + S^2)^(3/2),
    d2r/dS2 = -12 H^2 h S / (4 H^2 + S^2)^(5/2),

and every joint stays continuous. The machine's slot bounds the radius: 0 < r <=
max_crank_radius < pivot_distance. numpy only.
"""

import copy
import math
from typing import Optional, Tuple

from qrm_ros.core.common.checks import finite, KinematicsError, positive
from qrm_ros.core.kinematics.geometry import (crank_radius_for_stroke, Geometry,
                                              stroke_for_crank_radius)
from qrm_ros.core.numerics.ramps import ramp

__all__ = ['DEFAULT_STROKE_RATE_LIMIT', 'StrokeRamp', 'check_max_crank_radius',
           'check_stroke', 'crank_radius_motion', 'fixed_stroke', 'largest_stroke']

DEFAULT_STROKE_RATE_LIMIT = 0.01  # m/s of stroke: about 10 s for a 100 mm change by hand


def crank_radius_motion(stroke: float, stroke_rate: float, pivot_distance: float,
                        ram_height: float) -> Tuple[float, float, float]:
    """
    Return the crank radius (m), its rate (m/s) and acceleration (m/s^2) for a stroke.

    stroke (m) moves at the constant stroke_rate (m/s); the radius follows it through
    r = S h / sqrt(4 H^2 + S^2).
    """
    h, height = pivot_distance, ram_height
    four_h2 = 4.0 * height * height
    span2 = four_h2 + stroke * stroke
    span = math.sqrt(span2)
    radius = stroke * h / span
    slope = four_h2 * h / (span2 * span)
    curvature = -3.0 * four_h2 * h * stroke / (span2 * span2 * span)
    return radius, slope * stroke_rate, curvature * stroke_rate * stroke_rate


def check_max_crank_radius(geometry: Geometry, max_crank_radius: float) -> float:
    """Refuse a slot length the lever cannot take: 0 < max_crank_radius < pivot_distance."""
    value = finite('max_crank_radius', max_crank_radius, 'm')
    h = geometry.pivot_distance
    if not 0.0 < value < h:
        raise KinematicsError(
            f'max_crank_radius {value!r} m is out of range: allowed 0 < max_crank_radius < '
            f'pivot_distance = {h:.6g} m (at the pivot distance the lever turns fully round)')
    return value


def largest_stroke(geometry: Geometry, max_crank_radius: float) -> float:
    """Return the ram stroke (m) at the largest crank radius the slot allows."""
    radius = check_max_crank_radius(geometry, max_crank_radius)
    return float(stroke_for_crank_radius(radius, geometry.pivot_distance, geometry.ram_height))


def check_stroke(geometry: Geometry, stroke: float, max_crank_radius: float) -> float:
    """
    Refuse a stroke (m) whose crank radius is not in (0, max_crank_radius]; return it.

    The message names the value, the unit and the allowed range.
    """
    value = finite('stroke_length', stroke, 'm')
    limit = largest_stroke(geometry, max_crank_radius)
    if not 0.0 < value <= limit:
        raise KinematicsError(
            f'stroke_length {value!r} m is out of range: allowed 0 < stroke_length <= '
            f'{limit:.6g} m (crank radius up to max_crank_radius = {max_crank_radius:.6g} m)')
    return value


class StrokeRamp:
    """
    The ram stroke in force, its command and the rate limit it moves at (no ROS).

    Stepped like the offset: the stroke moves toward its command at rate_limit (m/s), each
    step exactly (a ramp is linear in time). ``geometry`` is the base geometry with the crank
    radius in force (one object per radius, so a steady stroke keeps one geometry).
    """

    def __init__(self, geometry: Geometry, max_crank_radius: float, stroke: float,
                 rate_limit: float) -> None:
        self._base = geometry
        self._max_radius = check_max_crank_radius(geometry, max_crank_radius)
        self._rate_limit = positive('stroke_rate_limit', rate_limit, 'm/s')
        self._geometry = geometry
        self._stroke = self._command = self.check(stroke)
        self._update_geometry()

    def check(self, stroke: float) -> float:
        """Return stroke (m) if the slot allows its crank radius; else KinematicsError."""
        return check_stroke(self._base, stroke, self._max_radius)

    def set_command(self, stroke: float) -> None:
        """Command the stroke (m); the stroke in force moves toward it at the rate limit."""
        self._command = self.check(stroke)

    def set_rate_limit(self, rate_limit: float) -> None:
        """Change the rate (m/s of stroke, > 0) at which the stroke follows its command."""
        self._rate_limit = positive('stroke_rate_limit', rate_limit, 'm/s')

    def reset(self, stroke: Optional[float] = None) -> None:
        """Stroke and command set at once, no ramp (None: leave both as they are)."""
        if stroke is None:
            return
        self._stroke = self._command = self.check(stroke)
        self._update_geometry()

    def move_to(self, stroke: float) -> None:
        """
        Take the stroke (m) a stepper reached on its own ramp (the motor stepper's).

        The same ramp as advance's, timed from the stepper's segment: stroke lies between
        the stroke in force and the command.
        """
        if stroke != self._stroke:
            self._stroke = stroke
            self._update_geometry()

    def _base_stroke(self) -> float:
        return float(self._base.ram_stroke)

    def advance(self, duration: float) -> None:
        """Move the stroke toward its command for duration (s) at the rate limit."""
        if self._stroke != self._command:
            self._stroke = ramp(self._stroke, self._command, self._rate_limit, duration)[0]
            self._update_geometry()

    def _update_geometry(self) -> None:
        self._geometry = self.geometry_at(self._stroke, self._geometry)

    def geometry_at(self, stroke: float, known: Optional[Geometry] = None) -> Geometry:
        """
        Return the base geometry with the crank radius of a stroke (m).

        The base itself at its own stroke (its radius, not a rounded one), known if it has
        that radius already (one object per radius: the caches keyed on it keep working).
        """
        base = self._base
        if stroke == self.base_stroke:
            return base
        radius = float(crank_radius_for_stroke(stroke, base.pivot_distance, base.ram_height))
        if known is not None and radius == known.crank_radius:
            return known
        # The base is a checked geometry of floats and the radius a checked stroke's (0 < r
        # <= max_crank_radius < pivot_distance): a copy with the radius set skips Geometry's
        # checks, most of a tick's cost while the stroke moves (each tick a new radius).
        geometry = copy.copy(base)
        object.__setattr__(geometry, 'crank_radius', radius)
        return geometry

    @property
    def base_stroke(self) -> float:
        """The stroke of the base geometry's crank radius, m."""
        return self._base_stroke()

    @property
    def geometry(self) -> Geometry:
        """The geometry with the crank radius in force."""
        return self._geometry

    @property
    def stroke(self) -> float:
        """Ram stroke in force, m."""
        return self._stroke

    @property
    def command(self) -> float:
        """Commanded ram stroke, m."""
        return self._command

    @property
    def rate(self) -> float:
        """Rate of the stroke from the present stamp on, m/s."""
        gap = self._command - self._stroke
        return math.copysign(self._rate_limit, gap) if gap else 0.0

    @property
    def rate_limit(self) -> float:
        return self._rate_limit

    @property
    def max_crank_radius(self) -> float:
        return self._max_radius

    @property
    def crank_radius(self) -> float:
        """Crank radius in force, m."""
        return float(self._geometry.crank_radius)

    def crank_radius_rates(self) -> Tuple[float, float]:
        """Rate (m/s) and acceleration (m/s^2) of the crank radius from the present stamp on."""
        rate = self.rate
        if not rate:
            return 0.0, 0.0
        base = self._base
        _, radius_rate, radius_acceleration = crank_radius_motion(
            self._stroke, rate, base.pivot_distance, base.ram_height)
        return radius_rate, radius_acceleration


def fixed_stroke(geometry: Geometry) -> StrokeRamp:
    """Return a stroke held at the geometry's (the slot ends at its crank radius)."""
    return StrokeRamp(geometry, float(geometry.crank_radius), float(geometry.ram_stroke),
                      DEFAULT_STROKE_RATE_LIMIT)
