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

speed_drive.peak_input_torque's loop, one configuration at a time, in the crank angle
phi_c (no coupling atan2). The revolution is split where the ram load switches (the two
reversals and the cutting stroke's workpiece edges, in closed form as
speed_drive.load_switch_angles, their sin and cos too; the other stroke's edges switch
nothing); each smooth piece carries its own constant ram force, taken at a point inside it.
Consecutive configurations that repeat the lever geometry or crank phase reuse these. The
samples come first: on each piece evenly spread crank angles (sin and cos by rotation, put
back onto the unit circle) and the coupling's two crossings (flywheel angle 0 or pi, where
the speed ratio changes fastest near |offset| = r1); piece ends with the piece's own force
(the one-sided limits at a workpiece edge). Then the torque and its slope
(dynamics.speed_drive_torque_of, compiled here) at all of them in one loop that LLVM
vectorises (SIMD lanes across samples). Then, in one branch-free pass, the intervals where
the slope changes sign, or where both slopes agree but the torque moved against them (a
minimum and a maximum hide there: halved until the change shows), and of those a bracket
is kept if the ends and slopes allow a peak of |torque| above the best sample. The
brackets are solved, largest bound first, by Brent's method on the slope, started where
the cubic through the ends' torques and slopes peaks and stopped once the torque's
possible gain is below its round-off. Blocks of configurations go to numba's threads one
at a time. Loading is as for qrm_ros.core.kinematics.peak_kernel: machine code compiled on the
first import for its one signature (about 8 s, with peak_kernel's) and cached, then 0.3 s
to load.
"""

import math

import numba
import numpy as np

from qrm_ros.core.dynamics.chain import speed_drive_torque_of
from qrm_ros.core.numerics.kernel_tools import compiler, rotate

_TWO_PI = 2.0 * math.pi
# Return-stroke samples grow as sqrt(h / (h - r)) times this, once above the base count.
_RETURN_DENSITY = 1.0
# Halvings of a sample interval that hides a minimum and a maximum, to find them.
_SPLIT_DEPTH = 20
# Configurations per block handed to a thread.
_BLOCK = 4096
# Samples per SIMD vector (AVX-512: 8 doubles); sample arrays are filled to whole vectors.
_LANES = 8
_EPSILON = float(np.finfo(np.float64).eps)
# Brent's method stops once the torque's possible gain is below this part of it (eps / 64).
_GAIN_RESOLUTION = _EPSILON / 64.0

_jit = compiler()
torque_of = _jit(speed_drive_torque_of)
# The same formula, inlined by numba itself (LLVM inlines only after its loop vectoriser
# ran), so that _evaluate's loop runs on SIMD lanes.
_torque_inline = numba.njit(cache=True, nogil=True, error_model='numpy',
                            fastmath={'contract'}, inline='always')(speed_drive_torque_of)


@_jit
def _turns(angle):
    """
    Return angle % 2 pi (the same float), without fmod's call for angles in (-2 pi, 4 pi).

    There angle - 2 pi is exact (as fmod), and angle + 2 pi rounds as Python's % does.
    """
    if angle >= 0.0:
        if angle < _TWO_PI:
            return angle
        if angle < 2.0 * _TWO_PI:
            return angle - _TWO_PI
    elif angle > -_TWO_PI:
        return angle + _TWO_PI
    return angle % _TWO_PI


@_jit
def _refine(low, high, low_torque, high_torque, low_slope, high_slope, low_sin, low_cos,
            high_sin, high_cos, force, best, tolerance, max_steps, geometry, inertia):
    """
    Return max(best, |torque| at the slope's root in [low, high]): Brent's method (zeroin).

    Started at the peak of the cubic through the ends' torques and slopes; then inverse
    quadratic and secant steps where they stay well inside the bracket, bisection
    otherwise; stops once the bracket is within tolerance (rad), or once the torque can
    gain no more than a small part of its round-off. Every point evaluated is a true
    torque of the piece, so the largest |torque| seen is kept. Each point's sin and cos
    come from rotating the previous point's by the step (no sin or cos calls once the
    steps are below 0.3 rad).
    """
    # The first point: where the cubic through both ends' torques and slopes peaks (its
    # slope, a quadratic in the fraction t of the bracket, changes sign once in (0, 1)).
    width = high - low
    mean = (high_torque - low_torque) / width
    square = 3.0 * (low_slope + high_slope - 2.0 * mean)
    linear = 2.0 * (3.0 * mean - 2.0 * low_slope - high_slope)
    root = math.sqrt(max(linear * linear - 4.0 * square * low_slope, 0.0))
    half_sum = -0.5 * (linear + math.copysign(root, linear))
    fraction = low_slope / half_sum
    if not 0.0 < fraction < 1.0:
        fraction = half_sum / square
        if not 0.0 < fraction < 1.0:
            fraction = low_slope / (low_slope - high_slope)  # the secant's
    fraction = min(max(fraction, 0.01), 0.99)
    step = fraction * width
    sin_b, cos_b = rotate(low_sin, low_cos, step)
    norm = 1.5 - 0.5 * (sin_b * sin_b + cos_b * cos_b)  # back onto the circle
    sin_b *= norm
    cos_b *= norm
    b = low + step
    torque, fb = torque_of(sin_b, cos_b, *geometry, force, *inertia)
    best = max(best, abs(torque))
    # Brent's state: b that point, c the end across the root, a the other end.
    if (fb > 0.0) == (low_slope > 0.0):
        a, fa, sin_a, cos_a = low, low_slope, low_sin, low_cos
        c, fc, sin_c, cos_c = high, high_slope, high_sin, high_cos
    else:
        a, fa, sin_a, cos_a = high, high_slope, high_sin, high_cos
        c, fc, sin_c, cos_c = low, low_slope, low_sin, low_cos
    d = e = b - a
    for _ in range(max_steps):
        if (fb > 0.0) == (fc > 0.0):
            c, fc, sin_c, cos_c = a, fa, sin_a, cos_a
            d = e = b - a
        if abs(fc) < abs(fb):
            a, fa, sin_a, cos_a = b, fb, sin_b, cos_b
            b, fb, sin_b, cos_b = c, fc, sin_c, cos_c
            c, fc, sin_c, cos_c = a, fa, sin_a, cos_a
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
        a, fa, sin_a, cos_a = b, fb, sin_b, cos_b
        step = d if abs(d) > tol else (tol if m > 0.0 else -tol)
        b += step
        sin_b, cos_b = rotate(sin_b, cos_b, step)
        norm = 1.5 - 0.5 * (sin_b * sin_b + cos_b * cos_b)  # back onto the circle
        sin_b *= norm
        cos_b *= norm
        torque, fb = torque_of(sin_b, cos_b, *geometry, force, *inertia)
        best = max(best, abs(torque))
        # Near the root torque(root) - torque(b) is about slope * step / 2, step the secant's
        # to the root: once that is far below the torque's round-off, no point can add more.
        if abs(fb * fb * (b - a)) <= _GAIN_RESOLUTION * abs(torque * (fb - fa)):
            break
    return best


@_jit
def _keep(kept, brackets, best, force, low, low_torque, low_slope, low_sin, low_cos, high,
          high_torque, high_slope, high_sin, high_cos):
    """Record [low, high] if the slope changes sign there and |torque| may beat best."""
    if (low_slope > 0.0 and high_slope < 0.0) or (low_slope < 0.0 and high_slope > 0.0):
        # |torque| can exceed the larger end by about half a slope times the gap between
        # them (a parabola's rise); twice that is the bound. (A parabola's peak from the
        # two ends plus 0.1 % and their difference lost peaks near |offset| = r1.)
        bound = (max(abs(low_torque), abs(high_torque))
                 + max(abs(low_slope), abs(high_slope)) * (high - low))
        if bound > best:
            kept[brackets, 0], kept[brackets, 1] = low, high
            kept[brackets, 2], kept[brackets, 3] = low_slope, high_slope
            kept[brackets, 4], kept[brackets, 5] = force, bound
            kept[brackets, 6], kept[brackets, 7] = low_sin, low_cos
            kept[brackets, 8], kept[brackets, 9] = high_sin, high_cos
            kept[brackets, 10], kept[brackets, 11] = low_torque, high_torque
            return brackets + 1
    return brackets


@_jit
def _evaluate(count, sines, cosines, forces, torques, slopes, r1, r, h, height, cos0, sin0,
              offset, clearance, speed, flywheel_inertia, lever_inertia, ram_mass,
              gravity_moment):
    """
    Torque and slope at the first count samples, into torques and slopes.

    The samples are independent, so LLVM runs this loop on SIMD lanes (several samples per
    instruction) instead of one sample's chain of divisions and square roots at a time.
    """
    for k in range(count):
        torques[k], slopes[k] = _torque_inline(sines[k], cosines[k], r1, r, h, height, cos0,
                                               sin0, offset, clearance, speed, forces[k],
                                               flywheel_inertia, lever_inertia, ram_mass,
                                               gravity_moment)


@_jit
def _edges(edges, r, h, height, cutting_length, start):
    """
    Write the crank angles (from start on) where the ram meets the workpiece's edges.

    With their sin and cos, in closed form, into edges' rows; return how many (0, 2 or 4).
    """
    count = 0
    if cutting_length > 0.0:
        for side in (1.0, -1.0):
            tangent = side * 0.5 * cutting_length / height
            secant = math.sqrt(1.0 + tangent * tangent)
            cosine = tangent * h / (r * secant)
            if abs(cosine) <= 1.0:
                spread = math.acos(cosine)
                sine = math.sqrt((1.0 - cosine) * (1.0 + cosine))
                shift = math.atan(tangent)
                for turn_sign in (1.0, -1.0):
                    # phi_c = +-spread - atan(tangent), by the angle-difference formulas.
                    edges[count, 0] = start + _turns(turn_sign * spread - shift - start)
                    edges[count, 1] = (turn_sign * sine - cosine * tangent) / secant
                    edges[count, 2] = (cosine + turn_sign * sine * tangent) / secant
                    count += 1
    return count


@_jit
def _peak_block(result, first, last, r1, r, h, height, phase, offset, speed,
                flywheel_inertia, lever_inertia, ram_mass, gravity_moment, cutting_force,
                ram_friction, cutting_length, cut_samples, return_samples, tolerance,
                max_steps):
    """Peak |input torque| (N m) of configurations first to last - 1, into result."""
    inertia = (flywheel_inertia, lever_inertia, ram_mass, gravity_moment)
    # Load switches in order, with their sin and cos (closed form, no sin or cos calls).
    bounds = np.empty((8, 3))
    # Each piece's first sample.
    piece_first = np.empty(8, np.int64)
    # Brackets kept from the samples: low, high, their slopes, force, bound, their sin, cos,
    # their torques.
    capacity = cut_samples + return_samples + 32 + _LANES
    kept = np.empty((capacity, 12))
    # Samples of the revolution: angle, sin, cos, force; torque and slope.
    angles, sines, cosines = np.empty(capacity), np.empty(capacity), np.empty(capacity)
    forces, torques, slopes = np.empty(capacity), np.empty(capacity), np.empty(capacity)
    # The intervals to look into; whether an interval lies inside a piece (all but between).
    marks = np.empty(capacity, np.int64)
    inside = np.ones(capacity, np.bool_)
    # The workpiece's edges in the crank angle (angle, sin, cos; before sorting), and the
    # lever geometry and crank phase they and cos0, sin0 were computed for: sweeps often
    # repeat them from one configuration to the next, and then reuse them.
    edges = np.empty((4, 3))
    edge_count = 0
    last_r = last_h = last_height = last_phase = math.nan
    cos0 = sin0 = half_gap = return_density = ratio = cos_gap = 0.0
    for i in range(first, last):
        ri, hi, heighti = r[i], h[i], height[i]
        if phase[i] != last_phase:
            last_phase = phase[i]
            cos0, sin0 = math.cos(last_phase), math.sin(last_phase)
        if ri != last_r or hi != last_h or heighti != last_height:
            last_r, last_h, last_height = ri, hi, heighti
            half_gap = math.asin(ri / hi)
            return_density = max(1.0, _RETURN_DENSITY * math.sqrt(hi / (hi - ri)))
            ratio = ri / hi
            cos_gap = math.sqrt((1.0 - ratio) * (1.0 + ratio))
            edge_count = _edges(edges, ri, hi, heighti, cutting_length, -half_gap)
        needed = cut_samples + int(math.ceil(return_samples * return_density)) + 32 + _LANES
        if needed > kept.shape[0]:
            kept = np.empty((needed, 12))
            angles, sines, cosines = np.empty(needed), np.empty(needed), np.empty(needed)
            forces, torques, slopes = np.empty(needed), np.empty(needed), np.empty(needed)
            marks, inside = np.empty(needed, np.int64), np.ones(needed, np.bool_)
        start = -half_gap
        turn = math.pi + half_gap
        # At both reversals sin(phi_c) = -r/h; cos(phi_c) = +-sqrt(1 - (r/h)^2).
        bounds[0, 0], bounds[0, 1], bounds[0, 2] = start, -ratio, cos_gap
        bounds[1, 0], bounds[1, 1], bounds[1, 2] = turn, -ratio, -cos_gap
        bounds[2, 0], bounds[2, 1], bounds[2, 2] = start + _TWO_PI, -ratio, cos_gap
        count = 3
        direction = 1.0 if speed[i] > 0.0 else -1.0
        for j in range(edge_count):
            # Only the cutting stroke's edges switch the load (ram friction alone on the
            # other stroke; x_c < 0 from the start to the turn).
            if (edges[j, 0] > turn) if direction > 0.0 else (edges[j, 0] < turn):
                continue
            bounds[count, 0], bounds[count, 1], bounds[count, 2] = (edges[j, 0], edges[j, 1],
                                                                    edges[j, 2])
            count += 1
        for j in range(3, count):  # insertion sort: at most two edges
            value, value_sin, value_cos = bounds[j, 0], bounds[j, 1], bounds[j, 2]
            k = j
            while bounds[k - 1, 0] > value:
                bounds[k, 0], bounds[k, 1], bounds[k, 2] = (bounds[k - 1, 0], bounds[k - 1, 1],
                                                            bounds[k - 1, 2])
                k -= 1
            bounds[k, 0], bounds[k, 1], bounds[k, 2] = value, value_sin, value_cos
        clearance = (r1[i] - offset[i]) * (r1[i] + offset[i])
        geometry = (r1[i], ri, hi, heighti, cos0, sin0, offset[i], clearance, speed[i])
        # Crank angles where the flywheel angle is 0 or pi: there sin_c, cos_c = +-(sin0, cos0).
        first_cross = start + _turns(phase[i] - start)
        second_cross = start + _turns(phase[i] + math.pi - start)
        first_sign = 1.0
        if second_cross < first_cross:
            first_cross, second_cross, first_sign = second_cross, first_cross, -1.0
        # The samples of every piece, in order: its ends (with its own force) and between
        # them the even samples and the coupling's crossings.
        samples = 0
        pieces = 0
        for piece in range(count - 1):
            low, high = bounds[piece, 0], bounds[piece + 1, 0]
            width = high - low
            if width <= 0.0:
                continue
            middle = 0.5 * (low + high)
            # Each stroke its own count: the return's arc narrows as sqrt(1 - r/h) when
            # r/h -> 1, the torque's features there (the lever's quick swing) as 1 - r/h.
            if middle < turn:
                intervals = max(1, int(math.ceil(cut_samples * width / (turn - start))))
            else:
                intervals = max(1, int(math.ceil(return_samples * return_density * width
                                                 / (start + _TWO_PI - turn))))
            spacing = width / intervals
            step_sin, step_cos = rotate(0.0, 1.0, spacing)
            sin_c, cos_c = bounds[piece, 1], bounds[piece, 2]
            # The next even sample's sin and cos, rotated from the previous one's and put
            # back onto the unit circle (one Newton step for 1 / sqrt): rotations drift off
            # it by k eps, and where h + r sin(phi_c) is small (r/h -> 1) a point off the
            # circle gives a torque 1e-11 off any true value.
            even_sin = sin_c * step_cos + cos_c * step_sin
            even_cos = cos_c * step_cos - sin_c * step_sin
            # The piece's load, from a point inside it: the first even sample, or the middle.
            if intervals > 1:
                inside_sin, inside_cos = even_sin, even_cos
            else:  # the middle: the chord's midpoint (less than half a turn) onto the circle
                inside_sin = sin_c + bounds[piece + 1, 1]
                inside_cos = cos_c + bounds[piece + 1, 2]
                length = math.sqrt(inside_sin * inside_sin + inside_cos * inside_cos)
                inside_sin /= length
                inside_cos /= length
            # The ram velocity's sign: x_c < 0 from the cut's start to its end reversal.
            velocity_sign = -direction if middle < turn else direction
            position = heighti * ri * inside_cos / (hi + ri * inside_sin)
            cutting = velocity_sign < 0.0 and abs(position) <= 0.5 * cutting_length
            force = (cutting_force if cutting else 0.0) - ram_friction * velocity_sign
            piece_first[pieces] = samples
            pieces += 1
            angles[samples], sines[samples], cosines[samples] = low, sin_c, cos_c
            forces[samples] = force
            samples += 1
            cross, cross_sign = first_cross, first_sign
            if cross <= low:
                cross, cross_sign = second_cross, -first_sign
                if cross <= low:
                    cross = math.inf
            k = 1
            while k <= intervals:
                if cross < high and cross < low + spacing * k:
                    angles[samples] = cross
                    sines[samples], cosines[samples] = cross_sign * sin0, cross_sign * cos0
                    if cross < second_cross:
                        cross, cross_sign = second_cross, -cross_sign
                    else:
                        cross = math.inf
                elif k == intervals:
                    angles[samples] = high
                    sines[samples], cosines[samples] = bounds[piece + 1, 1], bounds[piece + 1, 2]
                    k += 1
                else:
                    angles[samples] = low + spacing * k
                    sines[samples], cosines[samples] = even_sin, even_cos
                    even_sin, even_cos = (even_sin * step_cos + even_cos * step_sin,
                                          even_cos * step_cos - even_sin * step_sin)
                    norm = 1.5 - 0.5 * (even_sin * even_sin + even_cos * even_cos)
                    even_sin *= norm
                    even_cos *= norm
                    k += 1
                forces[samples] = force
                samples += 1
        piece_first[pieces] = samples
        # Whole vectors: the last ones filled with copies of the first sample.
        padded = samples + (-samples) % _LANES
        for k in range(samples, padded):
            sines[k], cosines[k], forces[k] = sines[0], cosines[0], forces[0]
        _evaluate(padded, sines, cosines, forces, torques, slopes, *geometry, *inertia)
        # The intervals that may hold a peak, marked without branches: the slope changes
        # sign, or both slopes have one sign but the torque moved the other way (a minimum
        # and a maximum hide between the samples, by the mean value theorem). Not the
        # zero-width ones between pieces.
        for piece in range(1, pieces):
            inside[piece_first[piece] - 1] = False
        best = abs(torques[samples - 1])
        marked = 0
        for k in range(samples - 1):
            best = max(best, abs(torques[k]))
            slope, next_slope = slopes[k], slopes[k + 1]
            change = (((slope > 0.0) & (next_slope < 0.0))
                      | ((slope < 0.0) & (next_slope > 0.0)))
            hidden = (((slope > 0.0) == (next_slope > 0.0))
                      & ((torques[k + 1] - torques[k]) * slope < 0.0))
            marks[marked] = k
            marked += (change | hidden) & inside[k]
        for piece in range(1, pieces):
            inside[piece_first[piece] - 1] = True
        brackets = 0
        for mark in range(marked):
            k = marks[mark]
            force = forces[k]
            angle, torque, slope = angles[k], torques[k], slopes[k]
            following, next_torque, next_slope = angles[k + 1], torques[k + 1], slopes[k + 1]
            if (slope > 0.0) == (next_slope > 0.0) and (next_torque - torque) * slope < 0.0:
                # A minimum and a maximum hide here: halve towards them until a sample's
                # slope shows the change.
                low_angle, low_torque, low_slope = angle, torque, slope
                high_angle, high_torque, high_slope = following, next_torque, next_slope
                low_sin, low_cos = sines[k], cosines[k]
                high_sin, high_cos = sines[k + 1], cosines[k + 1]
                for _ in range(_SPLIT_DEPTH):
                    half = 0.5 * (low_angle + high_angle)
                    half_sin, half_cos = math.sin(half), math.cos(half)
                    half_torque, half_slope = torque_of(half_sin, half_cos, *geometry, force,
                                                        *inertia)
                    best = max(best, abs(half_torque))
                    if half_slope == 0.0:
                        break
                    if (half_slope > 0.0) != (low_slope > 0.0):
                        brackets = _keep(kept, brackets, best, force, low_angle,
                                         low_torque, low_slope, low_sin, low_cos, half,
                                         half_torque, half_slope, half_sin, half_cos)
                        brackets = _keep(kept, brackets, best, force, half, half_torque,
                                         half_slope, half_sin, half_cos, high_angle,
                                         high_torque, high_slope, high_sin, high_cos)
                        break
                    if (half_torque - low_torque) * low_slope < 0.0:
                        high_angle, high_torque, high_slope = half, half_torque, half_slope
                        high_sin, high_cos = half_sin, half_cos
                    else:
                        low_angle, low_torque, low_slope = half, half_torque, half_slope
                        low_sin, low_cos = half_sin, half_cos
            else:
                brackets = _keep(kept, brackets, best, force, angle, torque, slope,
                                 sines[k], cosines[k], following, next_torque, next_slope,
                                 sines[k + 1], cosines[k + 1])
        # Largest bound first: once the highest peak is refined, most others fall below it.
        for _ in range(brackets):
            b = 0
            for j in range(1, brackets):
                if kept[j, 5] > kept[b, 5]:
                    b = j
            if kept[b, 5] <= best:
                break
            kept[b, 5] = -1.0
            best = _refine(kept[b, 0], kept[b, 1], kept[b, 10], kept[b, 11], kept[b, 2],
                           kept[b, 3], kept[b, 6], kept[b, 7], kept[b, 8], kept[b, 9],
                           kept[b, 4], best, tolerance,
                           max_steps, geometry, inertia)
        result[i] = best


@numba.njit('float64[::1](float64[::1], float64[::1], float64[::1], float64[::1], '
            'float64[::1], float64[::1], float64[::1], float64, float64, float64, float64, '
            'float64, float64, float64, int64, int64, float64, int64)', cache=True,
            nogil=True, parallel=True, error_model='numpy', fastmath={'contract'})
def _peak_torques(r1, r, h, height, phase, offset, speed, flywheel_inertia, lever_inertia,
                  ram_mass, gravity_moment, cutting_force, ram_friction, cutting_length,
                  cut_samples, return_samples, tolerance, max_steps):
    """Peak |input torque| (N m) of flat configuration arrays: peak_torques' loop."""
    size = offset.size
    result = np.empty(size)
    blocks = (size + _BLOCK - 1) // _BLOCK
    for block in numba.prange(blocks):
        _peak_block(result, block * _BLOCK, min(size, (block + 1) * _BLOCK), r1, r, h, height,
                    phase, offset, speed, flywheel_inertia, lever_inertia, ram_mass,
                    gravity_moment, cutting_force, ram_friction, cutting_length, cut_samples,
                    return_samples, tolerance, max_steps)
    return result


def peak_torques(r1: np.ndarray, r: np.ndarray, h: np.ndarray, height: np.ndarray,
                 phase: np.ndarray, offset: np.ndarray, speed: np.ndarray,
                 flywheel_inertia: float, lever_inertia: float, ram_mass: float,
                 gravity_moment: float, cutting_force: float, ram_friction: float,
                 cutting_length: float, cut_samples: int, return_samples: int,
                 tolerance: float, max_steps: int) -> np.ndarray:
    """
    Peak |input torque| (N m) of flat configuration arrays; samples per stroke.

    Blocks of configurations are shared among numba's threads (numba.set_num_threads), one
    at a time to whichever thread is free rather than equal shares handed out at the start:
    a thread slowed by other work on its core then takes fewer blocks. (Set here, outside
    the compiled loop: set inside, it would keep the loop from numba's cache.)
    """
    with numba.parallel_chunksize(1):
        return _peak_torques(r1, r, h, height, phase, offset, speed, flywheel_inertia,
                             lever_inertia, ram_mass, gravity_moment, cutting_force,
                             ram_friction, cutting_length, cut_samples, return_samples,
                             tolerance, max_steps)
