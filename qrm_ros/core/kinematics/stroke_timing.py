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
How long each stroke takes, and the ratios of the strokes' times and mid-stroke speeds.

For a positive input speed the slow stroke, which moves the ram toward -x (ram velocity
< 0), is the cutting stroke; running in reverse makes the cut the fast stroke (TR < 1).
Closed form through the coupling's inverse (doc/mechanism.md), with the paper's RK4
integration of eq. (20) kept as an independent cross-check. numpy only.
"""

import math
from typing import Tuple

import numpy as np

from qrm_ros.core.common.checks import checked_input_speed
from qrm_ros.core.kinematics.geometry import (ArrayLike, check_offset, float_or_array,
                                              FloatOrArray, Geometry, TWO_PI)
from qrm_ros.core.kinematics.mechanism_state import (forward_cut_input_arc,
                                                     input_angle_for_flywheel_angle,
                                                     reversal_flywheel_angles, state)

__all__ = ['speed_ratio', 'speed_ratio_eq25', 'stroke_times', 'time_ratio', 'time_ratio_rk4']


def stroke_times(geometry: Geometry, offset: ArrayLike,
                 input_speed: ArrayLike = 1.0) -> Tuple[FloatOrArray, FloatOrArray]:
    """(cutting time, return time) in seconds at a constant input speed (rad/s)."""
    input_speed = checked_input_speed(input_speed)
    forward_cut = forward_cut_input_arc(geometry, offset)
    reverse = np.asarray(input_speed) < 0.0
    cut_arc = np.where(reverse, TWO_PI - forward_cut, forward_cut)
    speed = np.abs(input_speed)
    return float_or_array(cut_arc / speed), float_or_array((TWO_PI - cut_arc) / speed)


def time_ratio(geometry: Geometry, offset: ArrayLike,
               input_speed: ArrayLike = 1.0) -> FloatOrArray:
    """
    Cutting time over return time, exact.

    Time is proportional to the input angle at a constant input speed, so TR is the ratio
    of the two input arcs between the reversal angles mapped back through the coupling.
    Only the sign of input_speed matters.
    """
    cutting, returning = stroke_times(geometry, offset, input_speed)
    return float_or_array(np.asarray(cutting) / returning)


def speed_ratio(geometry: Geometry, offset: ArrayLike,
                input_speed: ArrayLike = 1.0) -> FloatOrArray:
    """
    Return the paper's speed ratio (eq. 25): mid-return over mid-cut ram speed.

    Mid-stroke is where the lever is vertical.

    Evaluated through the general state (any crank phase); speed_ratio_eq25 is the paper's
    closed form for crank_phase = 0.
    """
    input_speed = checked_input_speed(input_speed)
    mid_cut = input_angle_for_flywheel_angle(geometry, offset,
                                             0.5 * math.pi - geometry.crank_phase)
    mid_return = input_angle_for_flywheel_angle(geometry, offset,
                                                -0.5 * math.pi - geometry.crank_phase)
    cut_speed = np.abs(state(geometry, offset, mid_cut, 1.0).ram_velocity)
    return_speed = np.abs(state(geometry, offset, mid_return, 1.0).ram_velocity)
    forward = return_speed / cut_speed
    return float_or_array(np.where(np.asarray(input_speed) < 0.0, 1.0 / forward, forward))


def speed_ratio_eq25(geometry: Geometry, offset: ArrayLike) -> FloatOrArray:
    """Paper eq. 25, SR = (h + r)(r1 + d) / ((h - r)(r1 - d)), valid for crank_phase = 0."""
    offset = check_offset(geometry, offset)
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    return float_or_array((h + r) * (r1 + offset) / ((h - r) * (r1 - offset)))


def _flywheel_speed_from_angle(flywheel_angle, offset, r1, input_speed):
    """Paper eq. (20): the flywheel speed written in terms of its own angle."""
    sin_p = math.sin(flywheel_angle)
    pin_distance = offset * sin_p + math.sqrt(r1 * r1 - (offset * math.cos(flywheel_angle)) ** 2)
    return input_speed * (r1 * r1 - offset * offset + offset * pin_distance * sin_p) / (
        pin_distance * pin_distance)


def time_ratio_rk4(geometry: Geometry, offset: float,
                   steps_per_revolution: int = 8192) -> float:
    """
    Time ratio the paper's way: integrate eq. (20) for the flywheel angle with classic RK4.

    An independent cross-check of time_ratio (it never inverts the coupling). Each reversal
    is landed on exactly by one last RK4 step taken in the flywheel angle (dt/dphi = 1/phi'),
    so the only error is RK4's own.
    """
    offset = float(check_offset(geometry, offset))
    r1 = geometry.coupling_radius
    step = TWO_PI / steps_per_revolution

    def rate(phi):
        return _flywheel_speed_from_angle(phi, offset, r1, 1.0)

    def duration(phi, target):
        elapsed = 0.0
        while True:
            k1 = rate(phi)
            k2 = rate(phi + 0.5 * step * k1)
            k3 = rate(phi + 0.5 * step * k2)
            k4 = rate(phi + step * k3)
            following = phi + step * (k1 + 2.0 * k2 + 2.0 * k3 + k4) / 6.0
            if following >= target:
                break
            phi, elapsed = following, elapsed + step
        gap = target - phi
        j1 = 1.0 / rate(phi)
        j2 = 1.0 / rate(phi + 0.5 * gap)
        j4 = 1.0 / rate(target)
        return elapsed + gap * (j1 + 4.0 * j2 + j4) / 6.0

    start, end = (float(a) for a in reversal_flywheel_angles(geometry))
    cutting = duration(start, end)
    returning = duration(end, start + TWO_PI)
    return cutting / returning
