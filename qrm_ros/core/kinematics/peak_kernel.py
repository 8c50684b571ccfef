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
Compiled (numba) peak search of peak_speeds.peak_ram_speeds for large design sweeps.

The same method as peak_speeds._peak_speeds_block, one configuration at a time: the sign of
d|v|/dphi_c (speed_rise.speed_rise_of, the very function, compiled) at evenly spread crank
angles and the coupling's two crossings, then safeguarded Newton steps on dv/dphi_c (the
closed-form slopes of peak_speeds._ram_speed_terms) in every bracket where |v| rises then
falls. The formulas are those of peak_speeds, written out for scalars; the tests hold the two
to agree to 1e-12 (they do to 5e-14). Imported only for sweeps big enough to repay loading it
(peak_speeds.COMPILED_MIN_CONFIGURATIONS): importing numba and loading the cached machine
code take 0.3 s (0.5-0.8 s on a busy machine); the first import compiles (2 s, 3-5 s busy),
cached beside this file (or in numba's user cache) until the file changes. peak_speeds is
compiled for its one signature on import, so no call can start another compilation.
"""

import math
from typing import Tuple

import numpy as np

from qrm_ros.core.numerics.kernel_tools import compiler, rotate
from qrm_ros.core.kinematics.speed_rise import speed_rise_of

__all__ = ['newton_peak', 'peak_speeds', 'velocity']

_TWO_PI = 2.0 * math.pi

_jit = compiler()
# d|v|/dphi_c's division-free numerator, speed_rise's formula compiled for scalars.
_speed_rise = _jit(speed_rise_of)


@_jit
def _flywheel_terms(sin_c, cos_c, r1, cos0, sin0, offset):
    """Return sin and cos of the flywheel angle (the crank's less its phase), and S (eq. 20)."""
    sin_f = sin_c * cos0 - cos_c * sin0
    cos_f = cos_c * cos0 + sin_c * sin0
    return sin_f, cos_f, math.sqrt(r1 * r1 - (offset * cos_f) ** 2)


@_jit
def velocity(sin_c: float, cos_c: float, r1: float, r: float, h: float, height: float,
             cos0: float, sin0: float, offset: float, clearance: float) -> float:
    """Ram velocity per unit input speed at a crank angle given by its sine and cosine."""
    sin_f, cos_f, root = _flywheel_terms(sin_c, cos_c, r1, cos0, sin0, offset)
    lift = offset * sin_f
    pin_distance = lift + root if lift >= 0.0 else clearance / (root - lift)
    denominator = h + r * sin_c
    return -height * r * (h * sin_c + r) / (denominator * denominator) * (root / pin_distance)


@_jit
def _velocity_growth_slope(sin_c, cos_c, r1, r, h, height, cos0, sin0, offset, clearance):
    """v, dv/dphi_c and d2v/dphi_c2: peak_speeds._ram_speed_terms, three divisions."""
    sin_f, cos_f, root = _flywheel_terms(sin_c, cos_c, r1, cos0, sin0, offset)
    lift = offset * sin_f
    inverse_root = 1.0 / root
    inverse_pin = 1.0 / (lift + root) if lift >= 0.0 else (root - lift) / clearance
    inverse_denominator = 1.0 / (h + r * sin_c)
    ratio = root * inverse_pin
    scale = -height * r * inverse_denominator * inverse_denominator
    slope1 = scale * (h * sin_c + r)
    bracket = h * h - 2.0 * r * r - h * r * sin_c
    scale *= inverse_denominator
    slope2 = scale * cos_c * bracket
    factor = offset * clearance * inverse_root * inverse_pin * inverse_pin
    ratio1 = -factor * cos_f
    growth = slope2 * ratio + slope1 * ratio1
    cos2 = cos_c * cos_c
    slope3 = scale * ((-sin_c * bracket - h * r * cos2)
                      - 3.0 * r * cos2 * bracket * inverse_denominator)
    offset_cos = offset * cos_f * inverse_root
    ratio2 = factor * (sin_f * (1.0 + offset_cos * offset_cos) + 2.0 * offset_cos * cos_f)
    return (slope1 * ratio, growth,
            slope3 * ratio + 2.0 * slope2 * ratio1 + slope1 * ratio2)


@_jit
def newton_peak(stroke_sign: float, low: float, sin_c: float, cos_c: float, start: float,
                high: float, tolerance: float, resolution: float, max_steps: int, r1: float,
                r: float, h: float, height: float, cos0: float, sin0: float, offset: float,
                clearance: float) -> Tuple[float, float]:
    """
    Root of dv/dphi_c in [low, high] and |v| there: peak_speeds.newton_peaks, one root.

    (sin_c, cos_c) are those of low; each step rotates them by its angle instead of calling
    sin and cos (the costliest part otherwise). The speed returned is the one at the last
    Newton point, at most a step (<= tolerance) short of the root, and carries the
    rotations' rounding (up to ~1e-14 where h sin(phi_c) + r cancels): enough to rank the
    peaks; the stroke's best is taken again at its root with sin and cos.
    """
    angle = start
    sin_c, cos_c = rotate(sin_c, cos_c, start - low)
    velocity = 0.0
    for _ in range(max_steps):
        velocity, growth, slope = _velocity_growth_slope(sin_c, cos_c, r1, r, h, height, cos0,
                                                         sin0, offset, clearance)
        if stroke_sign * growth > 0.0:
            low = angle
        else:
            high = angle
        step = growth / slope
        following = angle - step
        newton = stroke_sign * slope < 0.0 and following >= low and following <= high
        if not newton:
            following = 0.5 * (low + high)
        done = ((newton and abs(step) <= tolerance)
                or high - low <= resolution * max(abs(angle), 1.0))
        sin_c, cos_c = rotate(sin_c, cos_c, following - angle)
        angle = following
        if done:
            break
    return abs(velocity), angle


@_jit
def _keep_peak(best, best_angle, stroke_sign, angle, growth, sin_c, cos_c, end, end_growth,
               tolerance, resolution, max_steps, args):
    """Return the larger of (best, its angle) and the peak of |v| turning in [angle, end]."""
    if growth >= 0.0 and end_growth <= 0.0 and growth != end_growth:
        start = angle + (end - angle) * (growth / (growth - end_growth))
        speed, at = newton_peak(stroke_sign, angle, sin_c, cos_c, start, end, tolerance,
                                resolution, max_steps, *args)
        if speed > best:
            return speed, at
    return best, best_angle


@_jit
def _stroke_peak(stroke_sign, arc_start, arc_end, sin_end, cos_start, cos_end, samples,
                 tolerance, resolution, max_steps, phase, r1, r, h, height, cos0, sin0,
                 offset, clearance):
    """
    Largest |v| of one stroke: peak_speeds._peak_speeds_block for one configuration.

    sin and cos of every sample come from rotating those of the stroke's start (exact:
    sin = -r/h at both reversals) by the sample spacing.
    """
    args = (r1, r, h, height, cos0, sin0, offset, clearance)
    # Crank angles where the flywheel angle is 0 or pi (there sin_c, cos_c = +-(sin0, cos0)),
    # in order from the stroke's start.
    cross = arc_start + (phase - arc_start) % _TWO_PI
    cross_sin, cross_cos = sin0, cos0
    other = arc_start + (phase + math.pi - arc_start) % _TWO_PI
    if other < cross:
        cross, other = other, cross
        cross_sin, cross_cos = -sin0, -cos0
    width = arc_end - arc_start
    spacing = width / (samples + 1)
    step_sin, step_cos = rotate(0.0, 1.0, spacing)
    angle, sin_c, cos_c = arc_start, sin_end, cos_start
    growth = max(-stroke_sign * _speed_rise(sin_c, cos_c, r1, r, h, cos0, sin0, offset), 0.0)
    best, best_angle = 0.0, arc_start
    for k in range(1, samples + 2):
        if k == samples + 1:
            following, next_sin, next_cos = arc_end, sin_end, cos_end
            following_growth = min(-stroke_sign * _speed_rise(
                next_sin, next_cos, r1, r, h, cos0, sin0, offset), 0.0)
        else:
            following = arc_start + width * (k / (samples + 1))
            next_sin = sin_c * step_cos + cos_c * step_sin
            next_cos = cos_c * step_cos - sin_c * step_sin
            following_growth = -stroke_sign * _speed_rise(next_sin, next_cos, r1, r, h, cos0,
                                                          sin0, offset)
        # The coupling's crossings inside this interval are samples too.
        while cross < following:
            if cross > angle:
                cross_growth = -stroke_sign * _speed_rise(cross_sin, cross_cos, r1, r, h, cos0,
                                                          sin0, offset)
                best, best_angle = _keep_peak(best, best_angle, stroke_sign, angle, growth,
                                              sin_c, cos_c, cross, cross_growth, tolerance,
                                              resolution, max_steps, args)
                angle, growth, sin_c, cos_c = cross, cross_growth, cross_sin, cross_cos
            cross, cross_sin, cross_cos = other, -cross_sin, -cross_cos
            other = math.inf
        best, best_angle = _keep_peak(best, best_angle, stroke_sign, angle, growth, sin_c,
                                      cos_c, following, following_growth, tolerance, resolution,
                                      max_steps, args)
        angle, growth, sin_c, cos_c = following, following_growth, next_sin, next_cos
    if best == 0.0:
        return 0.0
    return abs(velocity(math.sin(best_angle), math.cos(best_angle), *args))


@compiler('UniTuple(float64[::1], 2)(float64[::1], float64[::1], float64[::1], float64[::1], '
          'float64[::1], float64[::1], int64, int64, float64, float64, int64)')
def peak_speeds(r1: np.ndarray, r: np.ndarray, h: np.ndarray, height: np.ndarray,
                phase: np.ndarray, offset: np.ndarray, cut_samples: int, return_samples: int,
                tolerance: float, resolution: float,
                max_steps: int) -> Tuple[np.ndarray, np.ndarray]:
    """
    Forward (cutting, return) peak |v| per unit input speed of flat configuration arrays.

    Sweeps often repeat a crank phase or lever geometry from one configuration to the
    next: their sines and arcsine are then reused, not computed again.
    """
    size = offset.size
    cutting = np.empty(size)
    returning = np.empty(size)
    last_phase, cos0, sin0 = 0.0, 1.0, 0.0
    last_r, last_h, ratio, half_gap, cos_gap = -1.0, -1.0, 0.0, 0.0, 1.0
    for i in range(size):
        if phase[i] != last_phase:
            last_phase = phase[i]
            cos0, sin0 = math.cos(last_phase), math.sin(last_phase)
        if r[i] != last_r or h[i] != last_h:
            last_r, last_h = r[i], h[i]
            ratio = last_r / last_h
            half_gap = math.asin(ratio)
            # At both reversals sin(phi_c) = -r/h; cos(phi_c) = +-sqrt(1 - (r/h)^2).
            cos_gap = math.sqrt((1.0 - ratio) * (1.0 + ratio))
        clearance = (r1[i] - offset[i]) * (r1[i] + offset[i])
        args = (phase[i], r1[i], r[i], h[i], height[i], cos0, sin0, offset[i], clearance)
        cutting[i] = _stroke_peak(-1.0, -half_gap, math.pi + half_gap, -ratio, cos_gap,
                                  -cos_gap, cut_samples, tolerance, resolution, max_steps,
                                  *args)
        returning[i] = _stroke_peak(1.0, math.pi + half_gap, _TWO_PI - half_gap, -ratio,
                                    -cos_gap, cos_gap, return_samples, tolerance, resolution,
                                    max_steps, *args)
    return cutting, returning
