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
Compiled (numba) search of the peak input torque under the ideal speed drive.

motor_drive.peak_input_torque's loop, one configuration at a time, in the crank angle
phi_c (no coupling atan2). The revolution is split where the ram load switches (the two
reversals and the workpiece's edges, closed form as motor_drive._load_switch_angles); each
smooth piece carries its own constant ram force. The torque and its slope
(dynamics.speed_drive_torque_of, compiled here) are sampled on each piece at evenly spread
crank angles and the coupling's two crossings (flywheel angle 0 or pi, where the speed ratio
changes fastest near |offset| = r1); piece ends are taken with the piece's own force (the
one-sided limits at a workpiece edge). Wherever the slope changes sign towards a peak of
|torque| a bracket is kept, with a bound on its peak from the end values and slopes (the
slope taken as monotonic between two samples); a bracket whose bound can beat the best value
found is solved by safeguarded secant steps on the slope. Loading is as for
qrm_ros.peak_kernel: cached machine code (compiled on the first import, for its one
signature), a few tenths of a second to load.
"""

import math

import numpy as np

from qrm_ros.dynamics import speed_drive_torque_of
from qrm_ros.peak_kernel import _compiler, _rotate

_TWO_PI = 2.0 * math.pi
# Return-stroke samples grow as sqrt(h / (h - r)) times this, once above the base count.
_RETURN_DENSITY = 0.6
_EPSILON = float(np.finfo(np.float64).eps)

_jit = _compiler()
_torque = _jit(speed_drive_torque_of)


@_jit
def _refine(low, high, low_slope, high_slope, force, best, tolerance, max_steps, geometry,
            inertia):
    """
    Return max(best, |torque| at the slope's root in [low, high]): Brent's method (zeroin).

    Inverse quadratic and secant steps where they stay well inside the bracket, bisection
    otherwise; stops once the bracket is within tolerance (rad). Every point evaluated is
    a true torque of the piece, so the largest |torque| seen is kept.
    """
    r1, r, h, height, cos0, sin0, offset, clearance, speed = geometry
    a, fa, b, fb = low, low_slope, high, high_slope
    c, fc = a, fa
    d = e = b - a
    for _ in range(max_steps):
        if (fb > 0.0) == (fc > 0.0):
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * _EPSILON * abs(b) + 0.5 * tolerance
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            break
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:
                p = 2.0 * m * s
                q = 1.0 - s
            else:
                q = fa / fc
                t = fb / fc
                p = s * (2.0 * m * q * (q - t) - (b - a) * (t - 1.0))
                q = (q - 1.0) * (t - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else (tol if m > 0.0 else -tol)
        torque, fb = _torque(math.sin(b), math.cos(b), r1, r, h, height, cos0, sin0, offset,
                             clearance, speed, force, *inertia)
        best = max(best, abs(torque))
    return best


@_compiler('float64[::1](float64[::1], float64[::1], float64[::1], float64[::1], '
           'float64[::1], float64[::1], float64[::1], float64, float64, float64, float64, '
           'float64, float64, float64, int64, int64, float64, int64)')
def peak_torques(r1, r, h, height, phase, offset, speed, flywheel_inertia, lever_inertia,
                 ram_mass, gravity_moment, cutting_force, ram_friction, cutting_length,
                 cut_samples, return_samples, tolerance, max_steps):
    """Peak |input torque| (N m) of flat configuration arrays; samples per stroke."""
    size = offset.size
    result = np.empty(size)
    inertia = (flywheel_inertia, lever_inertia, ram_mass, gravity_moment)
    bounds = np.empty(8)
    # Brackets kept from the samples: low, high, low slope, high slope, force, bound.
    kept = np.empty((cut_samples + return_samples + 16, 6))
    for i in range(size):
        cos0, sin0 = math.cos(phase[i]), math.sin(phase[i])
        ri, hi, heighti = r[i], h[i], height[i]
        half_gap = math.asin(ri / hi)
        return_density = max(1.0, _RETURN_DENSITY * math.sqrt(hi / (hi - ri)))
        start = -half_gap
        turn = math.pi + half_gap
        bounds[0], bounds[1], bounds[2] = start, turn, start + _TWO_PI
        count = 3
        if cutting_length > 0.0:
            for side in (1.0, -1.0):
                tangent = side * 0.5 * cutting_length / heighti
                cosine = tangent * hi / (ri * math.sqrt(1.0 + tangent * tangent))
                if abs(cosine) <= 1.0:
                    spread = math.acos(cosine)
                    for edge in (spread, -spread):
                        bounds[count] = start + (edge - math.atan(tangent) - start) % _TWO_PI
                        count += 1
        for j in range(3, count):  # insertion sort: at most four edges
            value = bounds[j]
            k = j
            while bounds[k - 1] > value:
                bounds[k] = bounds[k - 1]
                k -= 1
            bounds[k] = value
        geometry = (r1[i], ri, hi, heighti, cos0, sin0, offset[i],
                    (r1[i] - offset[i]) * (r1[i] + offset[i]), speed[i])
        direction = 1.0 if speed[i] > 0.0 else -1.0
        crossings = (start + (phase[i] - start) % _TWO_PI,
                     start + (phase[i] + math.pi - start) % _TWO_PI)
        first_cross = min(crossings[0], crossings[1])
        second_cross = max(crossings[0], crossings[1])
        best = 0.0
        brackets = 0
        for piece in range(count - 1):
            low, high = bounds[piece], bounds[piece + 1]
            width = high - low
            if width <= 0.0:
                continue
            middle = 0.5 * (low + high)
            # The ram velocity's sign: x_c < 0 from the cut's start to its end reversal.
            velocity_sign = -direction if middle < turn else direction
            position = heighti * ri * math.cos(middle) / (hi + ri * math.sin(middle))
            cutting = velocity_sign < 0.0 and abs(position) <= 0.5 * cutting_length
            force = (cutting_force if cutting else 0.0) - ram_friction * velocity_sign
            # Each stroke its own count: the return's arc narrows as sqrt(1 - r/h) when
            # r/h -> 1, the torque's features there (the lever's quick swing) as 1 - r/h.
            if middle < turn:
                intervals = max(1, int(math.ceil(cut_samples * width / (turn - start))))
            else:
                intervals = max(1, int(math.ceil(return_samples * return_density * width
                                                 / (start + _TWO_PI - turn))))
            spacing = width / intervals
            step_sin, step_cos = _rotate(0.0, 1.0, spacing)
            sin_c, cos_c = math.sin(low), math.cos(low)
            # sin and cos of the even samples: rotated from the previous even sample's.
            even_sin, even_cos = sin_c, cos_c
            angle = low
            torque, slope = _torque(sin_c, cos_c, *geometry, force, *inertia)
            best = max(best, abs(torque))
            cross = first_cross
            if cross <= low:
                cross = second_cross if second_cross > low else math.inf
            k = 1
            while k <= intervals:
                if cross < high and cross < low + spacing * k:
                    following = cross
                    next_sin, next_cos = math.sin(cross), math.cos(cross)
                    cross = second_cross if cross < second_cross else math.inf
                elif k == intervals:
                    following = high
                    next_sin, next_cos = math.sin(high), math.cos(high)
                    k += 1
                else:
                    following = low + spacing * k
                    even_sin, even_cos = (even_sin * step_cos + even_cos * step_sin,
                                          even_cos * step_cos - even_sin * step_sin)
                    next_sin, next_cos = even_sin, even_cos
                    k += 1
                next_torque, next_slope = _torque(next_sin, next_cos, *geometry, force,
                                                  *inertia)
                best = max(best, abs(next_torque))
                if (slope > 0.0 and next_slope < 0.0) or (slope < 0.0 and next_slope > 0.0):
                    # |torque| can exceed the larger end by about half a slope times the gap
                    # between them (a parabola's rise); twice that is kept as the margin.
                    bound = (max(abs(torque), abs(next_torque))
                             + max(abs(slope), abs(next_slope)) * (following - angle))
                else:
                    bound = -1.0
                if bound > best and brackets < kept.shape[0]:
                    kept[brackets, 0], kept[brackets, 1] = angle, following
                    kept[brackets, 2], kept[brackets, 3] = slope, next_slope
                    kept[brackets, 4], kept[brackets, 5] = force, bound
                    brackets += 1
                angle, sin_c, cos_c = following, next_sin, next_cos
                torque, slope = next_torque, next_slope
        for b in range(brackets):
            if kept[b, 5] > best:
                best = _refine(kept[b, 0], kept[b, 1], kept[b, 2], kept[b, 3], kept[b, 4],
                               best, tolerance, max_steps, geometry, inertia)
        result[i] = best
    return result
