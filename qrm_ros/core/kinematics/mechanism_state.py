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
The mechanism's exact state: every joint from the input shaft's angle, speed and acceleration.

The chain is input shaft -> offset yoke coupling -> flywheel -> crank pin -> slotted lever
-> ram. Both stages are the same inverted slider-crank, so one function serves both. Every
quantity is closed form, so published states carry no integration error; conventions and
equations follow doc/mechanism.md (x right, y up, angles counter-clockwise, lever
angle from the vertical toward +x, ram on a block at height ``ram_height`` above the pivot).
Also here: the coupling's inverse and the flywheel angles where the ram reverses, which
the stroke timing and the inverse problems map through. numpy only.
"""

import math
from typing import Any, Tuple

import numpy as np

from qrm_ros.core.numerics.portable_math import arcsin, arctan2, ARRAY_OPS, SCALAR_OPS
from qrm_ros.core.kinematics.geometry import (ArrayLike, check_offset, FloatOrArray, Geometry,
                                              MechanismState, TWO_PI)

__all__ = ['forward_cut_input_arc', 'input_angle_for_flywheel_angle',
           'reversal_flywheel_angles', 'state']


# The types of one sample of scalars (checked by type, not isinstance: numpy's float64 is a
# float and takes numpy's path).
_TEN_FLOATS = (float,) * 10
_PLAIN_NUMBERS = (float, int)


def _plain_zero(value):
    """Say whether value is a plain number equal to zero (arrays are taken as non-zero)."""
    return type(value) in (float, int) and value == 0


def _slot_rates(crank_radius, centre_distance, crank_angle, crank_speed, crank_acceleration,
                centre_rate=0.0, xp=ARRAY_OPS, radius_rate=0.0, radius_acceleration=0.0):
    """
    Angular rate and acceleration of the line from a slot's centre to a crank pin.

    The pin is at crank_radius (cos a, sin a) from the crank's centre, which sits
    centre_distance above the slot's centre (which may move at centre_rate). The pin may
    slide along the crank (radius_rate, radius_acceleration: the stroke adjustment). This is
    the inverted slider-crank of both stages; rates follow from the pin's relative position
    p, velocity and acceleration: beta' = (p x p') / |p|^2.
    """
    cos_a, sin_a = xp.cos(crank_angle), xp.sin(crank_angle)
    px = crank_radius * cos_a
    py = crank_radius * sin_a + centre_distance
    vx = -crank_radius * sin_a * crank_speed
    vy = crank_radius * cos_a * crank_speed + centre_rate
    ax = -px * crank_speed ** 2 - crank_radius * sin_a * crank_acceleration
    ay = -crank_radius * sin_a * crank_speed ** 2 + px * crank_acceleration
    if not (_plain_zero(radius_rate) and _plain_zero(radius_acceleration)):
        # The pin slides along the crank: its radial and Coriolis terms.
        vx = vx + radius_rate * cos_a
        vy = vy + radius_rate * sin_a
        ax = ax + radius_acceleration * cos_a - 2.0 * radius_rate * sin_a * crank_speed
        ay = ay + radius_acceleration * sin_a + 2.0 * radius_rate * cos_a * crank_speed
    norm2 = px * px + py * py
    cross_v = px * vy - py * vx
    rate = cross_v / norm2
    acceleration = (px * ay - py * ax) / norm2 - 2.0 * (px * vx + py * vy) * cross_v / norm2 ** 2
    return rate, acceleration


def state(geometry: Geometry, offset: ArrayLike, input_angle: ArrayLike,
          input_speed: ArrayLike, input_acceleration: ArrayLike = 0.0,
          offset_rate: ArrayLike = 0.0, crank_radius_rate: ArrayLike = 0.0,
          crank_radius_acceleration: ArrayLike = 0.0) -> MechanismState:
    """
    Exact state of every joint for an input shaft angle, speed and acceleration.

    offset_rate (m/s) adds the flywheel motion caused by a moving offset, so velocities are
    the true time derivatives of the positions while the offset actuator runs (its own
    acceleration is taken as zero: it moves at a constant rate or not at all).
    crank_radius_rate (m/s) and crank_radius_acceleration (m/s^2) add the lever's and the
    ram's motion caused by the stroke screw moving the crank pin along the crank; the crank
    radius in force is the geometry's.
    """
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    # One sample of scalars (the node, every tick) takes math's functions, not numpy's.
    scalar = tuple(map(type, (
        offset, input_angle, input_speed, input_acceleration, offset_rate, r1, r, h,
        geometry.ram_height, geometry.crank_phase))) == _TEN_FLOATS and (
            type(crank_radius_rate) in _PLAIN_NUMBERS
            and type(crank_radius_acceleration) in _PLAIN_NUMBERS)
    xp: Any
    if scalar and math.isfinite(offset) and abs(offset) < r1:  # type: ignore
        xp, theta = SCALAR_OPS, input_angle
    else:
        offset = check_offset(geometry, offset)
        xp, theta = ARRAY_OPS, np.asarray(input_angle, dtype=float)
    # Output angle = input angle + a bounded correction, so it is as continuous as the input.
    flywheel_angle = theta + xp.atan2(offset * xp.cos(theta), r1 + offset * xp.sin(theta))
    flywheel_speed, flywheel_acc = _slot_rates(r1, offset, theta, input_speed,
                                               input_acceleration, offset_rate, xp)
    crank_angle = flywheel_angle + geometry.crank_phase
    cos_c, sin_c = xp.cos(crank_angle), xp.sin(crank_angle)
    lever_angle = xp.atan2(r * cos_c, h + r * sin_c)
    slot_rate, slot_acc = _slot_rates(r, h, crank_angle, flywheel_speed, flywheel_acc, 0.0, xp,
                                      crank_radius_rate, crank_radius_acceleration)
    # The lever angle is measured from the vertical toward +x: the slot's angle, mirrored.
    lever_speed, lever_acc = -slot_rate, -slot_acc
    tan_lever = r * cos_c / (h + r * sin_c)
    sec2 = 1.0 + tan_lever * tan_lever
    height = geometry.ram_height
    result = MechanismState(
        flywheel_angle=flywheel_angle,
        flywheel_speed=flywheel_speed,
        lever_angle=lever_angle,
        lever_speed=lever_speed,
        ram_position=height * tan_lever,
        ram_velocity=height * lever_speed * sec2,
        ram_acceleration=height * sec2 * (lever_acc + 2.0 * lever_speed ** 2 * tan_lever),
    )
    if xp is SCALAR_OPS:
        return result
    if all(np.ndim(value) == 0 for value in result):
        return MechanismState(*(float(value) for value in result))
    return MechanismState(*(np.broadcast_arrays(*result)))


def input_angle_for_flywheel_angle(geometry: Geometry, offset: ArrayLike,
                                   flywheel_angle: ArrayLike) -> FloatOrArray:
    """Inverse of the coupling: the input angle that puts the flywheel at flywheel_angle."""
    offset = check_offset(geometry, offset)
    r1 = geometry.coupling_radius
    phi = np.asarray(flywheel_angle, dtype=float)
    sin_p, cos_p = np.sin(phi), np.cos(phi)
    pin_distance = offset * sin_p + np.sqrt(r1 * r1 - (offset * cos_p) ** 2)
    return arctan2(pin_distance * sin_p - offset, pin_distance * cos_p)


def reversal_flywheel_angles(geometry: Geometry) -> Tuple[FloatOrArray, FloatOrArray]:
    """
    Flywheel angles where the ram reverses: (start of the cut, end of the cut).

    For a positive input speed the cut starts at the ram's +x end (crank at -asin(r/h)) and
    covers the long arc through +90 degrees to pi + asin(r/h).
    """
    half_gap = arcsin(geometry.crank_radius / geometry.pivot_distance)
    return -half_gap - geometry.crank_phase, math.pi + half_gap - geometry.crank_phase


def forward_cut_input_arc(geometry: Geometry, offset: ArrayLike) -> FloatOrArray:
    """Input-shaft angle swept by the cutting stroke when running forward, in (0, 2 pi)."""
    start, end = reversal_flywheel_angles(geometry)
    theta_start = input_angle_for_flywheel_angle(geometry, offset, start)
    theta_end = input_angle_for_flywheel_angle(geometry, offset, end)
    return np.mod(theta_end - theta_start, TWO_PI)
