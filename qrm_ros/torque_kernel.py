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

import numba
import numpy as np

from qrm_ros.dynamics import speed_drive_torque_of
from qrm_ros.peak_kernel import _compiler, _rotate

_TWO_PI = 2.0 * math.pi

_jit = _compiler()
_torque = _jit(speed_drive_torque_of)


@_jit
def _refine(low, high, low_slope, high_slope, force, best, tolerance, resolution, max_steps,
            geometry, inertia):
    """Return max(best, |torque| at the slope's root in [low, high]), by safeguarded secant."""
    r1, r, h, height, cos0, sin0, offset, clearance, speed = geometry
    angle = low + (high - low) * (low_slope / (low_slope - high_slope))
    last, last_slope = low, low_slope
    for _ in range(max_steps):
        torque, slope = _torque(math.sin(angle), math.cos(angle), r1, r, h, height, cos0, sin0,
                                offset, clearance, speed, force, *inertia)
        best = max(best, abs(torque))
        if slope == 0.0 or high - low <= resolution * max(abs(angle), 1.0):
            break
        if (slope > 0.0) == (low_slope > 0.0):
            low, low_slope = angle, slope
        else:
            high, high_slope = angle, slope
        following = angle - slope * (angle - last) / (slope - last_slope)
        if not (following > low and following < high):
            following = 0.5 * (low + high)
        done = abs(following - angle) <= tolerance
        last, last_slope, angle = angle, slope, following
        if done:
            torque, slope = _torque(math.sin(angle), math.cos(angle), r1, r, h, height, cos0,
                                    sin0, offset, clearance, speed, force, *inertia)
            return max(best, abs(torque))
    return best


@_compiler('float64[::1](float64[::1], float64[::1], float64[::1], float64[::1], '
           'float64[::1], float64[::1], float64[::1], float64, float64, float64, float64, '
           'float64, float64, float64, int64, float64, float64, int64)')
def peak_torques(r1, r, h, height, phase, offset, speed, flywheel_inertia, lever_inertia,
                 ram_mass, gravity_moment, cutting_force, ram_friction, cutting_length,
                 samples, tolerance, resolution, max_steps):
    """Peak |input torque| (N m) of flat configuration arrays; samples per revolution."""
    size = offset.size
    result = np.empty(size)
    inertia = (flywheel_inertia, lever_inertia, ram_mass, gravity_moment)
    bounds = np.empty(8)
    # Brackets kept from the samples: low, high, low slope, high slope, force, bound.
    kept = np.empty((samples + 16, 6))
    for i in range(size):
        cos0, sin0 = math.cos(phase[i]), math.sin(phase[i])
        ri, hi, heighti = r[i], h[i], height[i]
        half_gap = math.asin(ri / hi)
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
        bounds[:count].sort()
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
            intervals = max(1, int(math.ceil(samples * width / _TWO_PI)))
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
                gap = following - angle
                if slope > 0.0 and next_slope < 0.0:  # a maximum of the torque
                    bound = min(torque + slope * gap, next_torque - next_slope * gap)
                elif slope < 0.0 and next_slope > 0.0:  # a minimum
                    bound = min(-torque - slope * gap, -next_torque + next_slope * gap)
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
                               best, tolerance, resolution, max_steps, geometry, inertia)
        result[i] = best
    return result
