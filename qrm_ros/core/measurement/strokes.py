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
Stroke reversals, stroke times and peak speeds from a sampled ram trajectory.

One method for every consumer (the node's live diagnostics and the offline analysis): between
two samples the ram position is the cubic Hermite interpolant of the sampled positions and
velocities, so reversals, mid-stroke points and speed peaks are located between samples
(errors of order dt^3 in velocity), never snapped to them. Pure numpy, no ROS.

Sign convention: a stroke whose ram velocity is negative (toward -x) is a cutting stroke; a
pair is a cutting stroke followed by a return stroke.

The two measurements also come in steps (``stroke_pair_steps``, ``pair_effort_steps``:
generators whose return value is the result, each step some tens of microseconds for a
pair of thousands of samples), so that a node's timer can measure between its ticks; the
plain functions run the same steps at once.
"""

import math
from typing import Generator, NamedTuple, Optional, Sequence, Tuple, TypeVar, Union

import numpy as np

from qrm_ros.core.measurement.piecewise_efforts import piecewise_figures

__all__ = ['PairEffortsMeasured', 'StrokePairs', 'find_reversals', 'find_stroke_pairs',
           'measure_pair_efforts', 'pair_effort_steps', 'run_steps', 'stroke_pair_steps',
           'workpiece_edge_times']

# Sampled values: a sequence of floats or a numpy array.
ArrayLike = Union[Sequence[float], np.ndarray]
Result = TypeVar('Result')
# A computation in steps: each next() runs one; its return value is the result.
Steps = Generator[None, None, Result]
# Newton iterations of the mid-stroke crossing: at most, and per step.
_NEWTON_ITERATIONS = 8
_NEWTON_ITERATIONS_PER_STEP = 2
# Pairs measured piece by piece in one step, and the samples beyond their ends a stencil
# may reach (a piece holding no sample borrows its neighbours').
_PAIRS_PER_STEP = 16
_BORROWED_SAMPLES = 2


def run_steps(steps: Steps[Result]) -> Result:
    """Run a computation in steps to its end and return its result."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


class StrokePairs(NamedTuple):
    """Per completed stroke pair (arrays of equal length; times in s, speeds in m/s)."""

    cutting_start: np.ndarray
    cutting_end: np.ndarray
    return_end: np.ndarray
    cutting_time: np.ndarray
    return_time: np.ndarray
    time_ratio: np.ndarray
    peak_cutting_speed: np.ndarray
    peak_return_speed: np.ndarray
    mid_cutting_speed: np.ndarray
    mid_return_speed: np.ndarray
    speed_ratio: np.ndarray
    peak_speed_ratio: np.ndarray
    # Cutting stroke length over cutting time (m/s): the cutting speed of shop tables.
    mean_cutting_speed: np.ndarray
    first_sample: np.ndarray
    last_sample: np.ndarray


def _hermite_velocity_coefficients(step, x0, x1, v0, v1):
    """Velocity of the Hermite cubic as a quadratic in s = (t - t0) / step: a s^2 + b s + c."""
    a = (6.0 * (x0 - x1) + 3.0 * step * (v0 + v1)) / step
    b = (6.0 * (x1 - x0) - step * (4.0 * v0 + 2.0 * v1)) / step
    return a, b, v0


def _hermite_position(s, step, x0, x1, v0, v1):
    s2 = s * s
    s3 = s2 * s
    # The basis 3 s^2 - 2 s^3 and 1 minus it: bit for bit -2 s^3 + 3 s^2 and 2 s^3 - 3 s^2 + 1
    # (rounding is symmetric: a - b is -(b - a), and 2 s^3 is exact), each worked out once.
    rise = 3 * s2 - 2 * s3
    return ((1 - rise) * x0 + (s3 - 2 * s2 + s) * step * v0
            + rise * x1 + (s3 - s2) * step * v1)


def _quadratic_root_in_unit(a, b, c):
    """Return the root in [0, 1] of a s^2 + b s + c, whose values at 0 and 1 differ in sign."""
    with np.errstate(divide='ignore', invalid='ignore'):
        disc = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
        q = -0.5 * (b + np.where(b >= 0.0, disc, -disc))
        first = q / a
        second = c / q
        linear = -c / b
    inside = (first >= 0.0) & (first <= 1.0)
    root = np.where(inside, first, second)
    root = np.where(np.abs(a) < 1e-12 * (np.abs(b) + np.abs(c)), linear, root)
    root[root != root] = 0.0  # no root (nan) -> 0; an infinite one goes to an end in the clip
    return np.clip(root, 0.0, 1.0)


def find_reversals(time: ArrayLike, ram_position: ArrayLike, ram_velocity: ArrayLike
                   ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Locate where the ram velocity changes sign, and the direction it turns to.

    Returns (times, cut_begins, intervals): cut_begins is True where the ram turns from
    moving toward +x to moving toward -x (a cutting stroke begins), False where a return
    begins; intervals holds the index of the sample each reversal follows.
    A velocity of exactly zero counts as positive, so a reversal landing on a sample is
    found once.
    """
    v = np.asarray(ram_velocity, dtype=float)
    return _reversals(_intervals(np.asarray(time, dtype=float),
                                 np.asarray(ram_position, dtype=float), v), v)


class _Intervals(NamedTuple):
    """The cubic Hermite interpolant on each interval between samples, worked out once."""

    start: np.ndarray  # s
    step: np.ndarray   # s, the interval's length
    x0: np.ndarray     # m, the positions and velocities at its ends
    x1: np.ndarray
    v0: np.ndarray     # m/s
    v1: np.ndarray
    a: Optional[np.ndarray]  # the velocity a s^2 + b s + v0, s = (t - start) / step
    b: Optional[np.ndarray]


def _intervals(t, x, v, quadratic=True):
    """Return the intervals of samples t, x, v (their velocity quadratics only if quadratic)."""
    step = np.diff(t)
    x0, x1, v0, v1 = x[:-1], x[1:], v[:-1], v[1:]
    a, b, _ = (_hermite_velocity_coefficients(step, x0, x1, v0, v1) if quadratic
               else (None, None, None))
    return _Intervals(t[:-1], step, x0, x1, v0, v1, a, b)


def _reversals(intervals, v):
    """find_reversals on the intervals of samples with velocities v."""
    positive = v >= 0.0
    k = np.nonzero(positive[:-1] != positive[1:])[0]
    start, step = intervals.start[k], intervals.step[k]
    s = _quadratic_root_in_unit(intervals.a[k], intervals.b[k], intervals.v0[k])
    return start + s * step, positive[k], k


def _interval_peak_speed(intervals):
    """Largest |velocity| of the Hermite interpolant on each sample interval."""
    a, b, c = intervals.a, intervals.b, intervals.v0
    with np.errstate(divide='ignore', invalid='ignore'):
        s = -b / (2.0 * a)
    interior = np.isfinite(s) & (s > 0.0) & (s < 1.0)
    s = np.where(interior, s, 0.0)
    extremum = np.where(interior, np.abs((a * s + b) * s + c), 0.0)
    return np.maximum(np.maximum(np.abs(intervals.v0), np.abs(intervals.v1)), extremum)


def _crossing_steps(intervals, x, level=0.0):
    """
    Find times and |velocity| where the ram (positions x) passes x = level (m), in steps.

    At level 0 the lever is vertical (the mid-stroke speeds); x - 0.0 is x, bit for bit, so
    there the intervals' own velocity quadratics are the crossing's.
    """
    above = x >= level
    k = np.nonzero(above[:-1] != above[1:])[0]
    interval_start, step = intervals.start[k], intervals.step[k]
    x0, x1 = intervals.x0[k] - level, intervals.x1[k] - level
    v0, v1 = intervals.v0[k], intervals.v1[k]
    with np.errstate(divide='ignore', invalid='ignore'):
        s = x0 / (x0 - x1)
    s[s != s] = 0.5  # 0/0: the middle; an infinite start goes to an end in the clip
    s = np.clip(s, 0.0, 1.0)
    # At level +0.0 (not -0.0: x - -0.0 turns -0.0 into 0.0) the intervals' own quadratic.
    if intervals.a is not None and level == 0.0 and math.copysign(1.0, level) > 0.0:
        a, b, c = intervals.a[k], intervals.b[k], v0
    else:
        a, b, c = _hermite_velocity_coefficients(step, x0, x1, v0, v1)
    # Newton on the cubic (the ram crosses x = 0 at near-peak speed), _NEWTON_ITERATIONS
    # times. Each iteration is a function of s alone: once s comes back to a value it had,
    # bit for bit (a fixed point, or a cycle in its last bits), the value after the last
    # iteration is known, and the loop stops there.
    seen = {s.tobytes(): 0}
    values = [s]
    for first in range(0, _NEWTON_ITERATIONS, _NEWTON_ITERATIONS_PER_STEP):
        yield
        with np.errstate(divide='ignore', invalid='ignore'):
            for iteration in range(first + 1, min(first + _NEWTON_ITERATIONS_PER_STEP,
                                                  _NEWTON_ITERATIONS) + 1):
                update = _hermite_position(s, step, x0, x1, v0, v1) / (
                    ((a * s + b) * s + c) * step)
                # A 0/0 update moves nothing (nan -> 0); an infinite one goes to an end of
                # [0, 1] through the clip, as the largest finite float did.
                update[update != update] = 0.0
                s = np.clip(s - update, 0.0, 1.0)
                earlier = seen.setdefault(s.tobytes(), iteration)
                if earlier != iteration:
                    s = values[earlier + (_NEWTON_ITERATIONS - earlier) % (iteration - earlier)]
                    return interval_start + s * step, np.abs((a * s + b) * s + c)
                values.append(s)
    return interval_start + s * step, np.abs((a * s + b) * s + c)


def workpiece_edge_times(time: ArrayLike, ram_position: ArrayLike, ram_velocity: ArrayLike,
                         cutting_start: ArrayLike, cutting_end: ArrayLike,
                         cutting_length: float) -> np.ndarray:
    """
    Return the times (s, sorted) where the tool meets or leaves the workpiece while cutting.

    The workpiece spans |x| <= cutting_length / 2 (m); an edge is where the cubic Hermite
    interpolant of the sampled ram positions and velocities crosses x = +-cutting_length / 2
    (found as the mid-stroke crossing is) inside a cutting stroke [cutting_start,
    cutting_end] (s).
    """
    t = np.asarray(time, dtype=float)
    x = np.asarray(ram_position, dtype=float)
    v = np.asarray(ram_velocity, dtype=float)
    start = np.asarray(cutting_start, dtype=float)
    end = np.asarray(cutting_end, dtype=float)
    if not (cutting_length > 0.0) or t.size < 2 or start.size == 0:
        return np.empty(0)
    intervals = _intervals(t, x, v, quadratic=False)  # off level 0: the crossing's own
    edges = np.sort(np.concatenate([run_steps(_crossing_steps(intervals, x, level))[0]
                                    for level in (0.5 * cutting_length, -0.5 * cutting_length)]))
    stroke = np.searchsorted(start, edges, side='right') - 1
    inside = (stroke >= 0) & (edges < end[np.maximum(stroke, 0)])
    return edges[inside]


def find_stroke_pairs(time: ArrayLike, ram_position: ArrayLike,
                      ram_velocity: ArrayLike) -> StrokePairs:
    """Every complete cutting + return stroke pair in a sampled run, with its measurements."""
    return run_steps(stroke_pair_steps(time, ram_position, ram_velocity))


def stroke_pair_steps(time: ArrayLike, ram_position: ArrayLike,
                      ram_velocity: ArrayLike) -> Steps[StrokePairs]:
    """find_stroke_pairs in steps."""
    t = np.asarray(time, dtype=float)
    x = np.asarray(ram_position, dtype=float)
    v = np.asarray(ram_velocity, dtype=float)
    empty = np.empty(0)
    if t.size < 3:
        return StrokePairs._make([empty] * 13 + [np.empty(0, int), np.empty(0, int)])
    intervals = _intervals(t, x, v)
    when, cut_begins, interval = _reversals(intervals, v)
    starts = np.nonzero(cut_begins[:-2] & ~cut_begins[1:-1] & cut_begins[2:])[0]
    returns, ends = starts + 1, starts + 2  # the reversals that begin the returns, end pairs
    cut_start, cut_end, ret_end = when[starts], when[returns], when[ends]
    yield

    peak = _interval_peak_speed(intervals)
    cumulative_max = _segment_max(peak, interval)
    peak_cut = cumulative_max[starts]
    peak_ret = cumulative_max[returns]

    cross_time, cross_speed = yield from _crossing_steps(intervals, x)
    yield
    # The mid-stroke speeds of the cutting strokes, then of the returns, in one search.
    mid_speeds = _first_between(cross_time, cross_speed, np.concatenate([cut_start, cut_end]),
                                np.concatenate([cut_end, ret_end]))
    mid_cut, mid_ret = mid_speeds[:starts.size], mid_speeds[starts.size:]
    cutting_time, return_time = cut_end - cut_start, ret_end - cut_end
    # Ram positions at the reversals, on the same Hermite interpolant that located them.
    step = intervals.step[interval]
    turn_position = _hermite_position(
        (when - intervals.start[interval]) / step, step, intervals.x0[interval],
        intervals.x1[interval], intervals.v0[interval], intervals.v1[interval])
    cutting_length = turn_position[starts] - turn_position[returns]
    with np.errstate(divide='ignore', invalid='ignore'):
        return StrokePairs(
            cutting_start=cut_start, cutting_end=cut_end, return_end=ret_end,
            cutting_time=cutting_time, return_time=return_time,
            time_ratio=cutting_time / return_time,
            peak_cutting_speed=peak_cut, peak_return_speed=peak_ret,
            mid_cutting_speed=mid_cut, mid_return_speed=mid_ret,
            speed_ratio=mid_ret / mid_cut, peak_speed_ratio=peak_ret / peak_cut,
            mean_cutting_speed=cutting_length / cutting_time,
            first_sample=interval[starts], last_sample=interval[ends] + 1)


def _segment_max(values, boundaries):
    """Max of values from each reversal's interval up to (not including) the next one's."""
    if boundaries.size < 2:
        return np.empty(0)
    return np.maximum.reduceat(values, boundaries)[:-1]


def _first_between(times, values, start, end):
    """Return the value at the first event inside each (start, end) window; NaN if none."""
    if times.size == 0:
        return np.full(start.shape, np.nan)
    index = np.minimum(np.searchsorted(times, start, side='right'), times.size - 1)
    at = times[index]
    found = (at > start) & (at < end)
    return np.where(found, values[index], np.nan)


class PairEffortsMeasured(NamedTuple):
    """Per stroke pair, from sampled input torque and speed (arrays; SI units)."""

    peak_input_torque: np.ndarray   # N·m, largest |input torque| in the pair
    rms_input_torque: np.ndarray    # N·m, over the pair's time
    mean_input_power: np.ndarray    # W, energy_per_pair / pair time
    energy_per_pair: np.ndarray     # J, integral of input torque x input speed
    peak_offset_force: np.ndarray   # N, largest |offset actuator force| in the pair
    speed_fluctuation: np.ndarray   # (max - min input speed) / mean input speed


class _PairEnds(NamedTuple):
    """Where the pairs' ends (ends then starts) fall among the samples: one for every signal."""

    sample: np.ndarray   # the sample each end follows (the last interval for an end beyond)
    since: np.ndarray    # s from that sample to the end
    spacing: np.ndarray  # s from that sample to the next
    half_step: np.ndarray  # s, half of each step between samples (the trapezoids)
    points: np.ndarray   # s, the starts and ends stacked (2, pairs)
    first: np.ndarray    # the first sample at or after each start
    last: np.ndarray     # one past the last sample at or before each end


def _pair_ends(t, start, end):
    when = np.concatenate([end, start])
    k = np.clip(np.searchsorted(t, when, side='right') - 1, 0, t.size - 2)
    at_sample = t[k]
    return _PairEnds(k, when - at_sample, t[k + 1] - at_sample, 0.5 * (t[1:] - t[:-1]),
                     np.stack([start, end]),
                     np.searchsorted(t, start, side='left'),
                     np.searchsorted(t, end, side='right'))


def _over_pairs(signals, ends):
    """Integral over each pair of each row's linear interpolant (trapezoids, ends interpolated)."""
    cumulative = np.zeros(signals.shape)
    np.cumsum(ends.half_step * (signals[:, 1:] + signals[:, :-1]), axis=1, out=cumulative[:, 1:])
    k, step = ends.sample, ends.since
    at_sample = signals[:, k]
    at = at_sample + (signals[:, k + 1] - at_sample) * step / ends.spacing
    up_to = cumulative[:, k] + 0.5 * step * (at_sample + at)
    pairs = k.size // 2
    return up_to[:, :pairs] - up_to[:, pairs:]


def _window_extremes(t, signals, ends):
    """Max and min of each row over each pair: samples inside plus the interpolated ends."""
    at_ends = np.stack([np.interp(ends.points, t, f) for f in signals])
    high, low = at_ends.max(axis=1), at_ends.min(axis=1)
    rows = range(len(signals))
    for index, (first, last) in enumerate(zip(ends.first.tolist(), ends.last.tolist())):
        if last > first:
            inside = signals[:, first:last]
            for row, top, bottom in zip(rows, inside.max(axis=1).tolist(),
                                        inside.min(axis=1).tolist()):
                high[row, index] = max(high[row, index], top)
                low[row, index] = min(low[row, index], bottom)
    return high, low


def measure_pair_efforts(time: ArrayLike, input_speed: ArrayLike, input_torque: ArrayLike,
                         offset_force: ArrayLike, pairs: StrokePairs,
                         workpiece_edges: Optional[ArrayLike] = None) -> PairEffortsMeasured:
    """
    Measure the effort figures of each pair in pairs (find_stroke_pairs, same samples).

    Without workpiece_edges, every signal is taken as linear between samples (trapezoid
    integrals, the pair's ends interpolated), so a load switch between two samples costs an
    error of order its jump x the sample spacing. With them (s: workpiece_edge_times,
    empty for a run without a workpiece), the torque and offset force
    are split there and at the pair's reversals and taken piece by piece
    (core.measurement.piecewise_efforts: fourth order within a piece, a jump's one-sided limits
    kept); a pair with a piece too short for that keeps the linear measure. These are
    measurements, compared with the exact theory of qrm_ros.core.dynamics. The mean input
    speed is the angle swept over the pair's time.
    """
    return run_steps(pair_effort_steps(time, input_speed, input_torque, offset_force, pairs,
                                       workpiece_edges))


def pair_effort_steps(time: ArrayLike, input_speed: ArrayLike, input_torque: ArrayLike,
                      offset_force: ArrayLike, pairs: StrokePairs,
                      workpiece_edges: Optional[ArrayLike] = None
                      ) -> Steps[PairEffortsMeasured]:
    """measure_pair_efforts in steps."""
    t = np.asarray(time, dtype=float)
    speed = np.asarray(input_speed, dtype=float)
    torque = np.asarray(input_torque, dtype=float)
    force = np.asarray(offset_force, dtype=float)
    start, end = pairs.cutting_start, pairs.return_end
    if start.size == 0:
        return PairEffortsMeasured._make([np.empty(0)] * len(PairEffortsMeasured._fields))

    ends = _pair_ends(t, start, end)
    duration = end - start
    power, squares = torque * speed, torque * torque
    yield
    # The three integrals in one pass over the signals stacked, as the three extremes.
    energy, torque_squared, angle = _over_pairs(np.stack([power, squares, speed]), ends)
    yield
    (torque_high, force_high, speed_high), (torque_low, force_low, speed_low) = (
        _window_extremes(t, np.stack([torque, force, speed]), ends))
    if workpiece_edges is not None:
        edges = np.asarray(workpiece_edges, dtype=float)
        switches = np.concatenate([start, pairs.cutting_end, end, edges])
        # A few pairs at a time, over their own samples (and the neighbours a stencil may
        # borrow): the memory stays that of a few pairs however long the run.
        for first in range(0, start.size, _PAIRS_PER_STEP):
            yield
            chosen = slice(first, first + _PAIRS_PER_STEP)
            low = max(0, int(np.searchsorted(t, start[chosen][0])) - _BORROWED_SAMPLES)
            high = int(np.searchsorted(t, end[chosen][-1])) + _BORROWED_SAMPLES
            window = slice(low, high)
            with np.errstate(all='ignore'):
                pieces = piecewise_figures(t[window], switches, start[chosen], end[chosen],
                                           (power[window], squares[window]),
                                           (torque[window], force[window]))
            fine = ~pieces.sparse
            for figure, found in ((energy, pieces.integrals[0]),
                                  (torque_squared, pieces.integrals[1]),
                                  (torque_high, pieces.highest[0]),
                                  (torque_low, pieces.lowest[0]),
                                  (force_high, pieces.highest[1]),
                                  (force_low, pieces.lowest[1])):
                figure[chosen] = np.where(fine, found, figure[chosen])
    with np.errstate(divide='ignore', invalid='ignore'):
        return PairEffortsMeasured(
            peak_input_torque=np.maximum(torque_high, -torque_low),
            rms_input_torque=np.sqrt(torque_squared / duration),
            mean_input_power=energy / duration,
            energy_per_pair=energy,
            peak_offset_force=np.maximum(force_high, -force_low),
            speed_fluctuation=(speed_high - speed_low) / np.abs(angle / duration))
