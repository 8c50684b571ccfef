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
The largest ram speeds of the cutting and the return stroke (the peaks need not be mid-stroke).

Each stroke is searched for every turning point of |ram velocity|: the sign of its slope
at evenly spread crank angles brackets each peak, and safeguarded Newton steps on closed-form
slopes solve it. Large sweeps take the same method compiled (qrm_ros.core.kinematics.peak_kernel,
numba, loaded only for them); the rest run it in numpy. numpy only.
"""

import math
from typing import Any, Callable, List, NamedTuple, Optional, Tuple

import numpy as np

from qrm_ros.core.common.checks import checked_input_speed
from qrm_ros.core.kinematics.geometry import (ArrayLike, check_offset, float_or_array,
                                              FloatOrArray, Geometry, TWO_PI)
from qrm_ros.core.numerics.portable_math import arcsin
from qrm_ros.core.kinematics.speed_rise import speed_rise_of

__all__ = ['BRACKET_RESOLUTION', 'COMPILED_MIN_CONFIGURATIONS', 'NEWTON_ANGLE_TOLERANCE',
           'NEWTON_MAX_STEPS', 'PEAK_SAMPLES', 'PeakProblem', 'compiled_peak_search',
           'flat_design', 'newton_peaks', 'peak_problem', 'peak_ram_speeds',
           'peak_speed_ratio', 'peak_speeds_forward', 'peak_speeds_numpy', 'speed_rise']

# Crank-angle samples inside the cutting and the return stroke that bracket their speed
# peaks before Newton's method. The cut can hold up to four peaks and the return two, some
# closer than 0.3 rad: against 48 and 32 samples, over 4 x 10^5 random designs (offsets up
# to 0.999 r1), 8 per stroke lost a peak in 3 of 10^5 (by up to 4.5e-4), 16 and 8 in 4 of
# 2 x 10^5 (up to 1.5e-3, two of them with r/h = 0.97), 24 and 12 in none.
PEAK_SAMPLES = (24, 12)
# Newton stops once a step is this small (rad): the error left is about its square, and the
# peak speed's error the square of that (the speed is stationary at its peak).
NEWTON_ANGLE_TOLERANCE = 1e-7
NEWTON_MAX_STEPS = 60
# Configurations per block of the peak search (keeps numpy's temporaries in cache).
_PEAK_BLOCK = 2048
# Sweeps of this many configurations or more take the compiled peak search: in a new
# process, importing numba and loading the cached machine code take 0.3 s (0.5-0.8 s on a
# busy machine; compiling, if the cache is missing or stale, 2-5 s), as long as numpy's
# search takes for about 10^5 configurations. Smaller sweeps (the node, the CLIs' tables and
# figures) never load it.
COMPILED_MIN_CONFIGURATIONS = 50_000
BRACKET_RESOLUTION = 4.0 * np.finfo(float).eps


class PeakProblem(NamedTuple):
    """Per-configuration constants of the peak search, as flat arrays."""

    coupling_radius: np.ndarray
    crank_radius: np.ndarray
    pivot_distance: np.ndarray
    ram_height: np.ndarray
    phase: np.ndarray
    cos_phase: np.ndarray
    sin_phase: np.ndarray
    offset: np.ndarray
    # (r1 - offset)(r1 + offset), formed without cancellation near |offset| = r1.
    clearance: np.ndarray

    def take(self, index: Any) -> 'PeakProblem':
        """Return the configurations picked by index (a slice, indices or a mask)."""
        return PeakProblem(*(field[index] for field in self))

    def column(self) -> 'PeakProblem':
        """Return each field as a column, to broadcast against rows of angles."""
        return PeakProblem(*(field[:, None] for field in self))


def _ram_speed_terms(crank_angle, problem, order):
    """
    Ram velocity per unit input speed as a function of the crank angle, and its slopes.

    Returns v, or (v, dv/dphi_c), or (v, dv/dphi_c, d2v/dphi_c2) for order 0, 1, 2.
    v = x'(phi_c) w(phi), the lever stage's slope dx/dphi_c times the coupling's speed ratio
    w = dphi/dtheta written in the flywheel angle (eq. 20 rearranged: w = S / r2, with
    S = sqrt(r1^2 - d^2 cos^2 phi) and r2 the pin's distance from the flywheel axis). All
    closed form; r2 is formed without cancellation, so |offset| -> r1 stays accurate.
    """
    r1, r, h, height, _, cos0, sin0, offset, clearance = problem
    sin_c, cos_c = np.sin(crank_angle), np.cos(crank_angle)
    sin_f = sin_c * cos0 - cos_c * sin0  # flywheel angle phi = phi_c - crank phase
    cos_f = cos_c * cos0 + sin_c * sin0
    root = np.sqrt(r1 * r1 - (offset * cos_f) ** 2)
    lift = offset * sin_f
    with np.errstate(divide='ignore', invalid='ignore'):
        pin_distance = np.where(lift >= 0.0, lift + root, clearance / (root - lift))
    ratio = root / pin_distance
    denominator = h + r * sin_c
    scale = -height * r
    slope1 = scale * (h * sin_c + r) / (denominator * denominator)
    velocity = slope1 * ratio
    if order == 0:
        return velocity
    bracket = h * h - 2.0 * r * r - h * r * sin_c
    cubed = denominator * denominator * denominator
    slope2 = scale * cos_c * bracket / cubed
    factor = offset * clearance / (root * pin_distance * pin_distance)
    ratio1 = -factor * cos_f
    growth = slope2 * ratio + slope1 * ratio1
    if order == 1:
        return velocity, growth
    cos2 = cos_c * cos_c
    slope3 = scale * ((-sin_c * bracket - h * r * cos2) / cubed
                      - 3.0 * r * cos2 * bracket / (cubed * denominator))
    ratio2 = factor * (sin_f * (1.0 + (offset * cos_f / root) ** 2)
                       + 2.0 * offset * cos_f * cos_f / root)
    return velocity, growth, slope3 * ratio + 2.0 * slope2 * ratio1 + slope1 * ratio2


def speed_rise(crank_angle: ArrayLike, problem: PeakProblem) -> FloatOrArray:
    """
    Return d|v|/dphi_c times a factor of the sign of h sin(phi_c) + r: cheap to sample.

    log|v| = log|x'(phi_c)| + log w, and the sum of their slopes, brought over the common
    denominator (h sin + r)(h + r sin) S^2 (S^2 = r1^2 - d^2 cos^2 phi > 0), leaves a
    numerator with one square root and no division. w'/w = -d cos(phi) (S - d sin(phi)) / S^2.
    """
    r1, r, h, _, _, cos0, sin0, offset, _ = problem
    return speed_rise_of(np.sin(crank_angle), np.cos(crank_angle), r1, r, h, cos0, sin0,
                         offset)


def flat_design(geometry: Geometry,
                offset: ArrayLike) -> Tuple[Tuple[int, ...], List[np.ndarray]]:
    """Broadcast shape, and (r1, r, h, ram height, crank phase, offset) as flat arrays."""
    offset = np.asarray(check_offset(geometry, offset), dtype=float)
    values = [np.asarray(v, dtype=float) for v in geometry.as_dict().values()] + [offset]
    shape = np.broadcast_shapes(*(v.shape for v in values))
    # Fresh arrays: one type (contiguous, writeable) for the compiled search's signature.
    return shape, [np.array(np.broadcast_to(v, shape).reshape(-1)) for v in values]


def peak_problem(geometry: Geometry,
                 offset: ArrayLike) -> Tuple[Tuple[int, ...], PeakProblem]:
    """Broadcast shape, and the peak search's constants of every configuration."""
    shape, flat = flat_design(geometry, offset)
    return shape, _problem_of(flat)


def _problem_of(flat):
    r1, r, h, height, phase, offset = flat
    return PeakProblem(r1, r, h, height, phase, np.cos(phase), np.sin(phase), offset,
                       (r1 - offset) * (r1 + offset))


def compiled_peak_search() -> Optional[Callable[..., Tuple[np.ndarray, np.ndarray]]]:
    """Return the compiled peak search, or None without numba (numpy's search then)."""
    try:
        # Deferred: numba is heavy (0.3 s or more to load) and optional; only large sweeps
        # come here.
        from qrm_ros.core.kinematics import peak_kernel
    except ImportError:
        return None
    return peak_kernel.peak_speeds


def peak_speeds_forward(geometry: Geometry,
                        offset: ArrayLike) -> Tuple[np.ndarray, np.ndarray]:
    """
    Largest |ram velocity| on the cut and on the return, per unit input speed.

    Sweeps of COMPILED_MIN_CONFIGURATIONS or more take the compiled search
    (qrm_ros.core.kinematics.peak_kernel), smaller ones the same method in numpy
    (peak_speeds_numpy).
    """
    shape, flat = flat_design(geometry, offset)
    search = (compiled_peak_search() if flat[0].size >= COMPILED_MIN_CONFIGURATIONS
              else None)
    if search is None:
        return _numpy_peak_search(shape, _problem_of(flat))
    cutting, returning = search(*flat, *PEAK_SAMPLES, NEWTON_ANGLE_TOLERANCE,
                                BRACKET_RESOLUTION, NEWTON_MAX_STEPS)
    return cutting.reshape(shape), returning.reshape(shape)


def peak_speeds_numpy(geometry: Geometry,
                      offset: ArrayLike) -> Tuple[np.ndarray, np.ndarray]:
    """Forward peak speeds by the numpy search at any size (the compiled one's reference)."""
    return _numpy_peak_search(*peak_problem(geometry, offset))


def _numpy_peak_search(shape, problem):
    """
    Forward peak speeds of flat configurations by numpy, reshaped to the sweep's shape.

    Configurations are taken in blocks small enough for numpy's temporaries to stay in the
    processor cache (several times faster than whole-array passes on large sweeps).
    """
    cutting = np.empty(problem.offset.size)
    returning = np.empty(problem.offset.size)
    for first in range(0, problem.offset.size, _PEAK_BLOCK):
        block = slice(first, first + _PEAK_BLOCK)
        cutting[block], returning[block] = _peak_speeds_block(problem.take(block))
    return cutting.reshape(shape), returning.reshape(shape)


def _peak_speeds_block(problem):
    """
    Peak cutting and return speeds of a block of configurations (flat arrays).

    Each stroke is sampled at evenly spread crank angles (where the motion is fastest the
    flywheel sweeps most angle, so crank-angle samples follow the speed peaks), plus two
    more where the coupling changes fastest. Wherever
    |v| rises at one sample and falls at the next (it always rises from a stroke's start
    and falls to its end) a peak is bracketed; safeguarded Newton steps on dv/dphi_c = 0
    with closed-form slopes solve it from the secant start. Samples placed at the
    factors' own turning points instead (mid-stroke, flywheel angles of +-90 degrees) were
    tried and fail: where the two coincide (crank phase 0) dv/dphi_c is zero there and the
    bracket is lost.
    """
    half_gap = arcsin(problem.crank_radius / problem.pivot_distance)
    peaks = []
    for stroke_sign, arc_start, arc_end, samples in (
            (-1.0, -half_gap, math.pi + half_gap, PEAK_SAMPLES[0]),
            (1.0, math.pi + half_gap, TWO_PI - half_gap, PEAK_SAMPLES[1])):
        fraction = np.linspace(0.0, 1.0, samples + 2)
        even = arc_start[:, None] + (arc_end - arc_start)[:, None] * fraction
        # Where the coupling pin crosses the line of centres (flywheel angle 0 or pi) its
        # speed ratio changes fastest; near |offset| = r1 a peak can hide between there
        # and a stroke's end, so both crossings (those inside the stroke) are sampled too.
        crossings = [np.clip(arc_start + np.mod(problem.phase + turn - arc_start, TWO_PI),
                             arc_start, arc_end) for turn in (0.0, math.pi)]
        angles = np.sort(np.column_stack([even] + crossings), axis=1)
        growth = speed_rise(angles, problem.column())
        growth *= -stroke_sign  # h sin(phi_c) + r is > 0 on the cut, < 0 on the return
        growth[:, 0] = np.maximum(growth[:, 0], 0.0)
        growth[:, -1] = np.minimum(growth[:, -1], 0.0)
        best = np.zeros(angles.shape[0])
        rows, cols = np.nonzero((growth[:, :-1] >= 0.0) & (growth[:, 1:] <= 0.0)
                                & (growth[:, :-1] != growth[:, 1:]))
        low, high = angles[rows, cols], angles[rows, cols + 1]
        rise, fall = growth[rows, cols], growth[rows, cols + 1]
        start = low + (high - low) * (rise / (rise - fall))
        at_root = newton_peaks(problem.take(rows), stroke_sign, start, low, high)
        np.maximum.at(best, rows, np.abs(at_root))
        peaks.append(best)
    return peaks[0], peaks[1]


def newton_peaks(problem: PeakProblem, stroke_sign: float, angle: np.ndarray, low: np.ndarray,
                 high: np.ndarray) -> np.ndarray:
    """
    Velocity at the root of dv/dphi_c near each start, within [low, high] (rtsafe).

    A Newton step that would leave the bracket is replaced by bisection, and the bracket
    shrinks with every evaluation, so each root is found even from a poor start.
    """
    everything = problem
    result = np.empty_like(angle)
    active = np.arange(angle.size)
    for _ in range(NEWTON_MAX_STEPS):
        _, growth, slope = _ram_speed_terms(angle, problem, 2)
        rising = stroke_sign * growth > 0.0
        low, high = np.where(rising, angle, low), np.where(rising, high, angle)
        with np.errstate(divide='ignore', invalid='ignore'):
            step = growth / slope
        following = angle - step
        # Only where |v| is concave does a Newton step head for a maximum; elsewhere (near
        # a speed minimum between two peaks) it could settle on the minimum: bisect instead.
        newton = (stroke_sign * slope < 0.0) & (following >= low) & (following <= high)
        following = np.where(newton, following, 0.5 * (low + high))
        done = ((newton & (np.abs(step) <= NEWTON_ANGLE_TOLERANCE))
                | (high - low <= BRACKET_RESOLUTION * np.maximum(np.abs(angle), 1.0)))
        result[active[done]] = following[done]
        keep = ~done
        if not np.any(keep):
            break
        active, angle, low, high = active[keep], following[keep], low[keep], high[keep]
        problem = problem.take(keep)
    else:
        result[active] = angle
    return _ram_speed_terms(result, everything, 0)


def peak_ram_speeds(geometry: Geometry, offset: ArrayLike,
                    input_speed: ArrayLike = 1.0) -> Tuple[FloatOrArray, FloatOrArray]:
    """(largest cutting speed, largest return speed) in m/s at a constant input speed."""
    input_speed = checked_input_speed(input_speed)
    forward_cut, forward_return = peak_speeds_forward(geometry, offset)
    speed = np.abs(input_speed)
    reverse = np.asarray(input_speed) < 0.0
    # Reversed, the ram retraces the same path: the forward return becomes the cut.
    cutting = np.where(reverse, forward_return, forward_cut) * speed
    returning = np.where(reverse, forward_cut, forward_return) * speed
    return float_or_array(cutting), float_or_array(returning)


def peak_speed_ratio(geometry: Geometry, offset: ArrayLike,
                     input_speed: ArrayLike = 1.0) -> FloatOrArray:
    """Largest return speed over largest cutting speed (the peaks need not be mid-stroke)."""
    cutting, returning = peak_ram_speeds(geometry, offset, input_speed)
    return float_or_array(np.asarray(returning) / cutting)
