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
Exact kinematics of the modified quick-return mechanism (pure numpy/scipy, no ROS).

The chain is input shaft -> offset yoke coupling -> flywheel -> crank pin -> slotted lever
-> ram. Both stages are the same inverted slider-crank, so one function serves both. Every
quantity is closed form, so published states carry no integration error; conventions and
equations follow doc/mechanism.md (x right, y up, angles counter-clockwise, lever
angle from the vertical toward +x, ram on a block at height ``ram_height`` above the pivot).

For a positive input speed the slow stroke, which moves the ram toward -x (ram velocity
< 0), is the cutting stroke; running in reverse makes the cut the fast stroke (TR < 1).
"""

import math
from typing import Any, NamedTuple, Tuple

import numpy as np
from scipy import optimize
from scipy.optimize import elementwise

from qrm_ros.core.geometry import (ArrayLike, as_float, check_offset, FloatOrArray, Geometry,
                                   KinematicsError, MechanismState, SAFE_OFFSET_FRACTION, TWO_PI)

__all__ = [
    'Geometry', 'KinematicsError', 'MechanismState', 'SAFE_OFFSET_FRACTION',
    'check_offset', 'input_angle_for_flywheel_angle', 'mean_cutting_speed',
    'offset_for_cutting_speed', 'offset_for_mean_cutting_speed',
    'offset_for_speed_ratio', 'offset_for_time_ratio', 'peak_ram_speeds', 'peak_speed_ratio',
    'reversal_flywheel_angles', 'speed_ratio', 'speed_ratio_eq25', 'state', 'stroke_times',
    'time_ratio', 'time_ratio_rk4',
]

# Inversions search |offset| <= this fraction of r1 (the open limit, short of the singularity).
_SEARCH_FRACTION = 1.0 - 1e-9
# Crank-angle samples inside the cutting and the return stroke that bracket their speed
# peaks before Newton's method. The cut can hold up to four peaks and the return two, some
# closer than 0.3 rad: against 48 and 32 samples, over 4 x 10^5 random designs (offsets up
# to 0.999 r1), 8 per stroke lost a peak in 3 of 10^5 (by up to 4.5e-4), 16 and 8 in 4 of
# 2 x 10^5 (up to 1.5e-3, two of them with r/h = 0.97), 24 and 12 in none.
_PEAK_SAMPLES = (24, 12)
# Newton stops once a step is this small (rad): the error left is about its square, and the
# peak speed's error the square of that (the speed is stationary at its peak).
_NEWTON_ANGLE_TOLERANCE = 1e-7
_NEWTON_MAX_STEPS = 60
# Configurations per block of the peak search (keeps numpy's temporaries in cache).
_PEAK_BLOCK = 2048
# Sweeps of this many configurations or more take the compiled peak search: in a new
# process, importing numba and loading the cached machine code take 0.3 s (0.5-0.8 s on a
# busy machine; compiling, if the cache is missing or stale, 2-5 s), as long as numpy's
# search takes for about 10^5 configurations. Smaller sweeps (the node, the CLIs' tables and
# figures) never load it.
_COMPILED_MIN_CONFIGURATIONS = 50_000
_BRACKET_RESOLUTION = 4.0 * np.finfo(float).eps


class _ScalarMath:
    """math's functions under numpy's names: the same formulas run ~20x faster on floats."""

    cos = staticmethod(math.cos)
    sin = staticmethod(math.sin)
    arctan2 = staticmethod(math.atan2)


def _slot_rates(crank_radius, centre_distance, crank_angle, crank_speed, crank_acceleration,
                centre_rate=0.0, xp=np):
    """
    Angular rate and acceleration of the line from a slot's centre to a crank pin.

    The pin is at crank_radius (cos a, sin a) from the crank's centre, which sits
    centre_distance above the slot's centre (which may move at centre_rate). This is the
    inverted slider-crank of both stages; rates follow from the pin's relative position
    p, velocity and acceleration: beta' = (p x p') / |p|^2.
    """
    cos_a, sin_a = xp.cos(crank_angle), xp.sin(crank_angle)
    px = crank_radius * cos_a
    py = crank_radius * sin_a + centre_distance
    vx = -crank_radius * sin_a * crank_speed
    vy = crank_radius * cos_a * crank_speed + centre_rate
    ax = -px * crank_speed ** 2 - crank_radius * sin_a * crank_acceleration
    ay = -crank_radius * sin_a * crank_speed ** 2 + px * crank_acceleration
    norm2 = px * px + py * py
    cross_v = px * vy - py * vx
    rate = cross_v / norm2
    acceleration = (px * ay - py * ax) / norm2 - 2.0 * (px * vx + py * vy) * cross_v / norm2 ** 2
    return rate, acceleration


def state(geometry: 'Geometry', offset: ArrayLike, input_angle: ArrayLike,
          input_speed: ArrayLike, input_acceleration: ArrayLike = 0.0,
          offset_rate: ArrayLike = 0.0) -> 'MechanismState':
    """
    Exact state of every joint for an input shaft angle, speed and acceleration.

    offset_rate (m/s) adds the flywheel motion caused by a moving offset, so velocities are
    the true time derivatives of the positions while the offset actuator runs (its own
    acceleration is taken as zero: it moves at a constant rate or not at all).
    """
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    # One sample of scalars (the node, every tick) takes math's functions, not numpy's.
    scalar = all(type(value) is float for value in (
        offset, input_angle, input_speed, input_acceleration, offset_rate, r1, r, h,
        geometry.ram_height, geometry.crank_phase))
    xp: Any
    if scalar and math.isfinite(offset) and abs(offset) < r1:  # type: ignore
        xp, theta = _ScalarMath, input_angle
    else:
        offset = check_offset(geometry, offset)
        xp, theta = np, np.asarray(input_angle, dtype=float)
    # Output angle = input angle + a bounded correction, so it is as continuous as the input.
    flywheel_angle = theta + xp.arctan2(offset * xp.cos(theta), r1 + offset * xp.sin(theta))
    flywheel_speed, flywheel_acc = _slot_rates(r1, offset, theta, input_speed,
                                               input_acceleration, offset_rate, xp)
    crank_angle = flywheel_angle + geometry.crank_phase
    cos_c, sin_c = xp.cos(crank_angle), xp.sin(crank_angle)
    lever_angle = xp.arctan2(r * cos_c, h + r * sin_c)
    slot_rate, slot_acc = _slot_rates(r, h, crank_angle, flywheel_speed, flywheel_acc, 0.0, xp)
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
    if xp is _ScalarMath:
        return result
    if all(np.ndim(value) == 0 for value in result):
        return MechanismState(*(float(value) for value in result))
    return MechanismState(*(np.broadcast_arrays(*result)))


def input_angle_for_flywheel_angle(geometry: 'Geometry', offset: ArrayLike,
                                   flywheel_angle: ArrayLike) -> FloatOrArray:
    """Inverse of the coupling: the input angle that puts the flywheel at flywheel_angle."""
    offset = check_offset(geometry, offset)
    r1 = geometry.coupling_radius
    phi = np.asarray(flywheel_angle, dtype=float)
    sin_p, cos_p = np.sin(phi), np.cos(phi)
    pin_distance = offset * sin_p + np.sqrt(r1 * r1 - (offset * cos_p) ** 2)
    return np.arctan2(pin_distance * sin_p - offset, pin_distance * cos_p)


def reversal_flywheel_angles(geometry: 'Geometry') -> Tuple[FloatOrArray, FloatOrArray]:
    """
    Flywheel angles where the ram reverses: (start of the cut, end of the cut).

    For a positive input speed the cut starts at the ram's +x end (crank at -asin(r/h)) and
    covers the long arc through +90 degrees to pi + asin(r/h).
    """
    half_gap = np.arcsin(geometry.crank_radius / geometry.pivot_distance)
    return -half_gap - geometry.crank_phase, math.pi + half_gap - geometry.crank_phase


def _forward_cut_input_arc(geometry, offset):
    """Input-shaft angle swept by the cutting stroke when running forward, in (0, 2 pi)."""
    start, end = reversal_flywheel_angles(geometry)
    theta_start = input_angle_for_flywheel_angle(geometry, offset, start)
    theta_end = input_angle_for_flywheel_angle(geometry, offset, end)
    return np.mod(theta_end - theta_start, TWO_PI)


def _check_speed(input_speed):
    input_speed = as_float('input_speed', input_speed)
    if np.any(np.asarray(input_speed) == 0.0):
        raise KinematicsError('input_speed must be non-zero (rad/s): a stopped shaft has no '
                              'strokes')
    return input_speed


def stroke_times(geometry: 'Geometry', offset: ArrayLike,
                 input_speed: ArrayLike = 1.0) -> Tuple[FloatOrArray, FloatOrArray]:
    """(cutting time, return time) in seconds at a constant input speed (rad/s)."""
    input_speed = _check_speed(input_speed)
    forward_cut = _forward_cut_input_arc(geometry, offset)
    reverse = np.asarray(input_speed) < 0.0
    cut_arc = np.where(reverse, TWO_PI - forward_cut, forward_cut)
    speed = np.abs(input_speed)
    return _scalar(cut_arc / speed), _scalar((TWO_PI - cut_arc) / speed)


def time_ratio(geometry: 'Geometry', offset: ArrayLike,
               input_speed: ArrayLike = 1.0) -> FloatOrArray:
    """
    Cutting time over return time, exact.

    Time is proportional to the input angle at a constant input speed, so TR is the ratio
    of the two input arcs between the reversal angles mapped back through the coupling.
    Only the sign of input_speed matters.
    """
    cutting, returning = stroke_times(geometry, offset, input_speed)
    return _scalar(np.asarray(cutting) / returning)


def speed_ratio(geometry: 'Geometry', offset: ArrayLike,
                input_speed: ArrayLike = 1.0) -> FloatOrArray:
    """
    Return the paper's speed ratio (eq. 25): mid-return over mid-cut ram speed.

    Mid-stroke is where the lever is vertical.

    Evaluated through the general state (any crank phase); speed_ratio_eq25 is the paper's
    closed form for crank_phase = 0.
    """
    input_speed = _check_speed(input_speed)
    mid_cut = input_angle_for_flywheel_angle(geometry, offset,
                                             0.5 * math.pi - geometry.crank_phase)
    mid_return = input_angle_for_flywheel_angle(geometry, offset,
                                                -0.5 * math.pi - geometry.crank_phase)
    cut_speed = np.abs(state(geometry, offset, mid_cut, 1.0).ram_velocity)
    return_speed = np.abs(state(geometry, offset, mid_return, 1.0).ram_velocity)
    forward = return_speed / cut_speed
    return _scalar(np.where(np.asarray(input_speed) < 0.0, 1.0 / forward, forward))


def speed_ratio_eq25(geometry: 'Geometry', offset: ArrayLike) -> FloatOrArray:
    """Paper eq. 25, SR = (h + r)(r1 + d) / ((h - r)(r1 - d)), valid for crank_phase = 0."""
    offset = check_offset(geometry, offset)
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    return _scalar((h + r) * (r1 + offset) / ((h - r) * (r1 - offset)))


def _scalar(value):
    return float(value) if np.ndim(value) == 0 else value


class _PeakProblem(NamedTuple):
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

    def take(self, index):
        return _PeakProblem(*(field[index] for field in self))

    def column(self):
        return _PeakProblem(*(field[:, None] for field in self))


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


def _speed_rise(crank_angle, problem):
    """
    Return d|v|/dphi_c times a factor of the sign of h sin(phi_c) + r: cheap to sample.

    log|v| = log|x'(phi_c)| + log w, and the sum of their slopes, brought over the common
    denominator (h sin + r)(h + r sin) S^2 (S^2 = r1^2 - d^2 cos^2 phi > 0), leaves a
    numerator with one square root and no division. w'/w = -d cos(phi) (S - d sin(phi)) / S^2.
    """
    r1, r, h, _, _, cos0, sin0, offset, _ = problem
    return speed_rise_of(np.sin(crank_angle), np.cos(crank_angle), r1, r, h, cos0, sin0,
                         offset)


def speed_rise_of(sin_c, cos_c, r1, r, h, cos0, sin0, offset):
    """
    Return _speed_rise from the crank angle's sine and cosine (arrays or floats).

    numpy only, so qrm_ros.core.peak_kernel compiles this same formula for its scalar loop.
    """
    offset_cos = offset * (cos_c * cos0 + sin_c * sin0)
    offset_sin = offset * (sin_c * cos0 - cos_c * sin0)
    root2 = r1 * r1 - offset_cos * offset_cos
    lever = (h * sin_c + r) * (h + r * sin_c)
    return (cos_c * ((h * h - 2.0 * r * r) - h * r * sin_c) * root2
            - offset_cos * (np.sqrt(root2) - offset_sin) * lever)


def _flat_design(geometry, offset):
    """Broadcast shape, and (r1, r, h, ram height, crank phase, offset) as flat arrays."""
    offset = np.asarray(check_offset(geometry, offset), dtype=float)
    values = [np.asarray(v, dtype=float) for v in geometry.as_dict().values()] + [offset]
    shape = np.broadcast_shapes(*(v.shape for v in values))
    # Fresh arrays: one type (contiguous, writeable) for the compiled search's signature.
    return shape, [np.array(np.broadcast_to(v, shape).reshape(-1)) for v in values]


def _peak_problem(geometry, offset):
    shape, flat = _flat_design(geometry, offset)
    return shape, _problem_of(flat)


def _problem_of(flat):
    r1, r, h, height, phase, offset = flat
    return _PeakProblem(r1, r, h, height, phase, np.cos(phase), np.sin(phase), offset,
                        (r1 - offset) * (r1 + offset))


def _compiled_peak_search():
    """Return the compiled peak search, or None without numba (numpy's search then)."""
    try:
        from qrm_ros.core import peak_kernel
    except ImportError:
        return None
    return peak_kernel.peak_speeds


def _peak_speeds_forward(geometry, offset):
    """
    Largest |ram velocity| on the cut and on the return, per unit input speed.

    Sweeps of _COMPILED_MIN_CONFIGURATIONS or more take the compiled search
    (qrm_ros.core.peak_kernel), smaller ones the same method in numpy (_peak_speeds_numpy).
    """
    shape, flat = _flat_design(geometry, offset)
    search = (_compiled_peak_search() if flat[0].size >= _COMPILED_MIN_CONFIGURATIONS
              else None)
    if search is None:
        return _numpy_peak_search(shape, _problem_of(flat))
    cutting, returning = search(*flat, *_PEAK_SAMPLES, _NEWTON_ANGLE_TOLERANCE,
                                _BRACKET_RESOLUTION, _NEWTON_MAX_STEPS)
    return cutting.reshape(shape), returning.reshape(shape)


def _peak_speeds_numpy(geometry, offset):
    """Forward peak speeds by the numpy search at any size (the compiled one's reference)."""
    return _numpy_peak_search(*_peak_problem(geometry, offset))


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
    half_gap = np.arcsin(problem.crank_radius / problem.pivot_distance)
    peaks = []
    for stroke_sign, arc_start, arc_end, samples in (
            (-1.0, -half_gap, math.pi + half_gap, _PEAK_SAMPLES[0]),
            (1.0, math.pi + half_gap, TWO_PI - half_gap, _PEAK_SAMPLES[1])):
        fraction = np.linspace(0.0, 1.0, samples + 2)
        even = arc_start[:, None] + (arc_end - arc_start)[:, None] * fraction
        # Where the coupling pin crosses the line of centres (flywheel angle 0 or pi) its
        # speed ratio changes fastest; near |offset| = r1 a peak can hide between there
        # and a stroke's end, so both crossings (those inside the stroke) are sampled too.
        crossings = [np.clip(arc_start + np.mod(problem.phase + turn - arc_start, TWO_PI),
                             arc_start, arc_end) for turn in (0.0, math.pi)]
        angles = np.sort(np.column_stack([even] + crossings), axis=1)
        growth = _speed_rise(angles, problem.column())
        growth *= -stroke_sign  # h sin(phi_c) + r is > 0 on the cut, < 0 on the return
        growth[:, 0] = np.maximum(growth[:, 0], 0.0)
        growth[:, -1] = np.minimum(growth[:, -1], 0.0)
        best = np.zeros(angles.shape[0])
        rows, cols = np.nonzero((growth[:, :-1] >= 0.0) & (growth[:, 1:] <= 0.0)
                                & (growth[:, :-1] != growth[:, 1:]))
        low, high = angles[rows, cols], angles[rows, cols + 1]
        rise, fall = growth[rows, cols], growth[rows, cols + 1]
        start = low + (high - low) * (rise / (rise - fall))
        at_root = _newton_peaks(problem.take(rows), stroke_sign, start, low, high)
        np.maximum.at(best, rows, np.abs(at_root))
        peaks.append(best)
    return peaks[0], peaks[1]


def _newton_peaks(problem, stroke_sign, angle, low, high):
    """
    Velocity at the root of dv/dphi_c near each start, within [low, high] (rtsafe).

    A Newton step that would leave the bracket is replaced by bisection, and the bracket
    shrinks with every evaluation, so each root is found even from a poor start.
    """
    everything = problem
    result = np.empty_like(angle)
    active = np.arange(angle.size)
    for _ in range(_NEWTON_MAX_STEPS):
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
        done = ((newton & (np.abs(step) <= _NEWTON_ANGLE_TOLERANCE))
                | (high - low <= _BRACKET_RESOLUTION * np.maximum(np.abs(angle), 1.0)))
        result[active[done]] = following[done]
        keep = ~done
        if not np.any(keep):
            break
        active, angle, low, high = active[keep], following[keep], low[keep], high[keep]
        problem = problem.take(keep)
    else:
        result[active] = angle
    return _ram_speed_terms(result, everything, 0)


def _peak_speeds_bracketing(geometry, offset, samples=48):
    """
    Run the previous method, kept as the reference of tests and the benchmark's baseline.

    Forward (cutting, return) peaks per unit input speed: extrema bracketed on a grid of
    flywheel angles, each solved where the ram acceleration crosses zero by scipy's
    vectorised Chandrupatla root finder, every evaluation through state().
    """
    offset = np.asarray(check_offset(geometry, offset), dtype=float)
    shape = np.broadcast_shapes(offset.shape, *(np.shape(v) for v in geometry.as_dict().values()))
    fields = [np.broadcast_to(np.asarray(v, dtype=float), shape).reshape(-1)
              for v in [offset] + list(geometry.as_dict().values())]
    start, end = reversal_flywheel_angles(Geometry(*fields[1:]))
    fraction = np.linspace(0.0, 1.0, samples + 1)[1:-1]
    peaks = []
    for arc_start, arc_end in ((start, end), (end, start + TWO_PI)):
        grid = arc_start[:, None] + (arc_end - arc_start)[:, None] * fraction[None, :]
        args = [f[:, None] for f in fields]
        sampled = _state_on_arc(grid, *args)
        best = np.abs(sampled.ram_velocity).max(axis=1)
        # d|v|/dt changes sign from + to - at a speed maximum: v * a goes + -> -.
        growth = sampled.ram_velocity * sampled.ram_acceleration
        rows, cols = np.nonzero((growth[:, :-1] > 0.0) & (growth[:, 1:] <= 0.0))
        if rows.size:
            row_args = [f[rows] for f in fields]
            result = elementwise.find_root(
                _bracketing_growth, (grid[rows, cols], grid[rows, cols + 1]),
                args=tuple(row_args),
                tolerances={'xatol': 1e-15, 'xrtol': 4 * np.finfo(float).eps})
            at_root = np.abs(_state_on_arc(result.x, *row_args).ram_velocity)
            np.maximum.at(best, rows, at_root)
        peaks.append(best.reshape(shape))
    return peaks[0], peaks[1]


def _state_on_arc(flywheel_angle, offset, r1, r, h, height, phase):
    geometry = Geometry(r1, r, h, height, phase)
    theta = input_angle_for_flywheel_angle(geometry, offset, flywheel_angle)
    return state(geometry, offset, theta, 1.0)


def _bracketing_growth(flywheel_angle, *args):
    sampled = _state_on_arc(flywheel_angle, *args)
    return sampled.ram_velocity * sampled.ram_acceleration


def peak_ram_speeds(geometry: 'Geometry', offset: ArrayLike,
                    input_speed: ArrayLike = 1.0) -> Tuple[FloatOrArray, FloatOrArray]:
    """(largest cutting speed, largest return speed) in m/s at a constant input speed."""
    input_speed = _check_speed(input_speed)
    forward_cut, forward_return = _peak_speeds_forward(geometry, offset)
    speed = np.abs(input_speed)
    reverse = np.asarray(input_speed) < 0.0
    # Reversed, the ram retraces the same path: the forward return becomes the cut.
    cutting = np.where(reverse, forward_return, forward_cut) * speed
    returning = np.where(reverse, forward_cut, forward_return) * speed
    return _scalar(cutting), _scalar(returning)


def peak_speed_ratio(geometry: 'Geometry', offset: ArrayLike,
                     input_speed: ArrayLike = 1.0) -> FloatOrArray:
    """Largest return speed over largest cutting speed (the peaks need not be mid-stroke)."""
    cutting, returning = peak_ram_speeds(geometry, offset, input_speed)
    return _scalar(np.asarray(returning) / cutting)


class SteadyTheory(NamedTuple):
    """Exact figures of steady running at one offset and input speed (s, m/s, ratios)."""

    cutting_time: FloatOrArray
    return_time: FloatOrArray
    time_ratio: FloatOrArray
    speed_ratio: FloatOrArray
    peak_speed_ratio: FloatOrArray
    peak_cutting_speed: FloatOrArray
    peak_return_speed: FloatOrArray


def steady_theory(geometry: 'Geometry', offset: ArrayLike,
                  input_speed: ArrayLike) -> 'SteadyTheory':
    """
    Every theory figure of steady running, from one place.

    The node's diagnostics, the recording analysis and the design table all compare with
    (or print) these; computing them once here keeps the three from drifting apart.
    """
    cutting, returning = stroke_times(geometry, offset, input_speed)
    peak_cut, peak_return = peak_ram_speeds(geometry, offset, input_speed)
    return SteadyTheory(
        cutting_time=cutting, return_time=returning,
        time_ratio=_scalar(np.asarray(cutting) / returning),
        speed_ratio=speed_ratio(geometry, offset, input_speed),
        peak_speed_ratio=_scalar(np.asarray(peak_return) / peak_cut),
        peak_cutting_speed=peak_cut, peak_return_speed=peak_return)


def offset_for_speed_ratio(geometry: 'Geometry', speed_ratio_target: ArrayLike) -> FloatOrArray:
    """Offset giving a mid-stroke speed ratio (eq. 27; numerical inversion if phased)."""
    target = as_float('speed_ratio', speed_ratio_target)
    if target <= 0.0:
        raise KinematicsError(f'speed_ratio must be > 0, got {speed_ratio_target!r}')
    if geometry.crank_phase == 0.0:
        r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
        offset = r1 * (target * (h - r) - (h + r)) / (target * (h - r) + (h + r))
        return check_offset(geometry, offset)
    return _invert(lambda d: speed_ratio(geometry, d), target, geometry, 'speed_ratio')


def offset_for_time_ratio(geometry: 'Geometry', time_ratio_target: ArrayLike) -> FloatOrArray:
    """Offset giving a wanted time ratio (forward running), by inverting the exact TR."""
    target = as_float('time_ratio', time_ratio_target)
    return _invert(lambda d: time_ratio(geometry, d), target, geometry, 'time_ratio')


def offset_for_cutting_speed(geometry: 'Geometry', input_speed: ArrayLike,
                             cutting_speed: ArrayLike) -> FloatOrArray:
    """Offset giving a wanted peak cutting speed (m/s) at an input speed (rad/s)."""
    input_speed = _check_speed(input_speed)
    target = as_float('cutting_speed', cutting_speed)
    return _invert(lambda d: peak_ram_speeds(geometry, d, input_speed)[0], target, geometry,
                   'cutting_speed')


def mean_cutting_speed(geometry: 'Geometry', offset: ArrayLike,
                       input_speed: ArrayLike) -> FloatOrArray:
    """
    Ram stroke over cutting time (m/s), exact: the cutting speed shop tables give.

    At a fixed offset it is proportional to |input_speed|, as the peak cutting speed is.
    """
    cutting, _ = stroke_times(geometry, offset, input_speed)
    return _scalar(geometry.ram_stroke / np.asarray(cutting))


def offset_for_mean_cutting_speed(geometry: 'Geometry', input_speed: ArrayLike,
                                  cutting_speed: ArrayLike) -> FloatOrArray:
    """
    Offset giving a wanted mean cutting speed (m/s) at an input speed (rad/s); vectorised.

    The cut needs the input arc A = stroke |input_speed| / cutting_speed. The forward cut's
    arc is strictly monotone in the offset: differentiating the inverse coupling,
    dA/d(offset) = f(cos(a + p)) + f(cos(a - p)) with f(c) = c / sqrt(r1^2 - offset^2 c^2)
    odd and increasing (a = asin(r/h), p = crank_phase), so its sign is that of cos(p)
    (positive for the paper's p = 0: a positive offset slows the cut). The root is therefore
    unique; at cos(p) = 0 the offset leaves the cutting speed unchanged and only that one
    speed is reachable.
    """
    input_speed = _check_speed(input_speed)
    target = as_float('cutting_speed', cutting_speed)
    if np.any(np.asarray(target) <= 0.0):
        raise KinematicsError(f'cutting_speed must be > 0 m/s, got {cutting_speed!r}')
    arc = geometry.ram_stroke * np.abs(input_speed) / target
    forward_arc = np.where(np.asarray(input_speed) < 0.0, TWO_PI - arc, arc)
    fields = np.broadcast_arrays(forward_arc, *(np.asarray(value, dtype=float) for value in
                                                geometry.as_dict().values()))
    flat = [np.array(field, dtype=float).reshape(-1) for field in fields]
    limit = _SEARCH_FRACTION * flat[1]
    below, above = (_cut_arc_error(side * limit, *flat) for side in (-1.0, 1.0))
    reachable = (np.minimum(below, above) <= 0.0) & (np.maximum(below, above) >= 0.0)
    if not np.all(reachable):
        i = int(np.argmin(reachable))
        one = Geometry(*(field[i] for field in flat[1:]))
        speed = float(np.broadcast_to(input_speed, fields[0].shape).flat[i])
        slowest, fastest = sorted(mean_cutting_speed(one, side * limit[i], speed)
                                  for side in (-1.0, 1.0))
        raise KinematicsError(
            f'cutting_speed {float(np.broadcast_to(target, fields[0].shape).flat[i]):g} m/s '
            f'is out of reach at input_speed {speed:g} rad/s: offsets with |offset| < '
            f'coupling_radius = {one.coupling_radius:g} m give mean cutting speeds from '
            f'{slowest:.6g} to {fastest:.6g} m/s')
    result = elementwise.find_root(
        _cut_arc_error, (-limit, limit), args=tuple(flat),
        tolerances={'xatol': 1e-17, 'xrtol': 4 * np.finfo(float).eps})
    return _scalar(result.x.reshape(fields[0].shape))


def _cut_arc_error(offset, forward_arc, r1, r, h, height, phase):
    geometry = Geometry(r1, r, h, height, phase)
    return _forward_cut_input_arc(geometry, offset) - forward_arc


def _invert(function, target, geometry, name):
    """
    Smallest-|offset| solution of function(offset) = target over |offset| < r1.

    Brackets come from a grid dense near the ends (where the mechanism changes fastest);
    each is then solved to machine precision with Brent's method.
    """
    limit = _SEARCH_FRACTION * geometry.coupling_radius
    offsets = limit * np.sin(np.linspace(-0.5 * math.pi, 0.5 * math.pi, 801))
    values = np.asarray(function(offsets)) - target
    exact = np.nonzero(values == 0.0)[0]
    candidates = [offsets[i] for i in exact]
    for i in np.nonzero(values[:-1] * values[1:] < 0.0)[0]:
        candidates.append(optimize.brentq(lambda d: float(function(d)) - target,
                                          offsets[i], offsets[i + 1], xtol=1e-17,
                                          rtol=4 * np.finfo(float).eps))
    if not candidates:
        low, high = np.min(values) + target, np.max(values) + target
        raise KinematicsError(
            f'{name} {target:g} is out of reach: offsets with |offset| < coupling_radius = '
            f'{geometry.coupling_radius:g} m give {name} from {low:.6g} to {high:.6g}')
    return float(min(candidates, key=abs))


def _flywheel_speed_from_angle(flywheel_angle, offset, r1, input_speed):
    """Paper eq. (20): the flywheel speed written in terms of its own angle."""
    sin_p = math.sin(flywheel_angle)
    pin_distance = offset * sin_p + math.sqrt(r1 * r1 - (offset * math.cos(flywheel_angle)) ** 2)
    return input_speed * (r1 * r1 - offset * offset + offset * pin_distance * sin_p) / (
        pin_distance * pin_distance)


def time_ratio_rk4(geometry: 'Geometry', offset: float,
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
