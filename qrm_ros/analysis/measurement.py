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
Measurement of a recorded run against the closed form, one steady segment at a time.

In each segment every stroke pair is measured (qrm_ros.core.measurement.strokes: reversals and
peaks located between samples): the time ratio TR, the speed ratio SR, stroke times and speeds,
and, when the joint states carry them, the drive's efforts, speed fluctuation and flywheel
speed swing. Each figure's mean and spread over the pairs stands beside its theory for the
recorded geometry and drive, with the relative error.
"""

import contextlib
import dataclasses
import math
from typing import Any, Dict, List, NamedTuple, Optional, Tuple

import numpy as np
from scipy import interpolate

from qrm_ros.analysis.recorded_drive import Drive
from qrm_ros.analysis.recorded_run import Recording, Samples
from qrm_ros.analysis.segments import Segment, split_segments
from qrm_ros.analysis.theory import flywheel_speed_swing
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.effort_theory import (EFFORT_FIGURES, Setting,
                                                    steady_effort_theory_and_problem,
                                                    THEORY_FIGURES, ZERO_CAN_BE_EXACT)
from qrm_ros.core.measurement.joint_consistency import misplaced_stamps
from qrm_ros.core.measurement.effort_sampling_bounds import (EFFORT_BOUNDED_FIGURES,
                                                             effort_sampling_bounds,
                                                             steady_efforts, switch_shift)
from qrm_ros.core.measurement.sampling_bounds import (BOUNDED_FIGURES, figure_sampling_bounds,
                                                      step_on_grid, steady_motion,
                                                      SUPPORTED_RELATIVE_ERROR)
from qrm_ros.core.measurement.strokes import (find_stroke_pairs, measure_pair_efforts,
                                              workpiece_edge_times)

# Every figure given a bound from the sampling: the stroke's, then the drive's.
ALL_BOUNDED_FIGURES = BOUNDED_FIGURES + EFFORT_BOUNDED_FIGURES

# A pair whose longest step exceeds its median step this many times (a late or lost
# sample) has its effort figures bounded at each stretch's own steps.
_IRREGULAR_STEPS = 1.05


def finite_or_none(value: Any) -> Any:
    """Map NaN and infinities (and numpy scalars) to JSON-safe values, recursively."""
    if isinstance(value, dict):
        return {key: finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def _relative_error(measured: float, theory: float) -> Optional[float]:
    if not (math.isfinite(measured) and math.isfinite(theory)) or theory == 0.0:
        return None
    return measured / theory - 1.0


def _mean_and_spread(values) -> Tuple[Optional[float], Optional[float]]:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return None, None
    spread = float(np.std(values, ddof=1)) if values.size > 1 else 0.0
    return float(np.mean(values)), spread


def _speed_extremes(time: np.ndarray, angle: np.ndarray, speed: np.ndarray,
                    starts: np.ndarray, ends: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """
    Max and min of a sampled speed over each [start, end], between samples too.

    The angle is taken as scipy's cubic Hermite interpolant of the sampled angles and speeds
    (its derivative matches every sample), so a peak between samples is found where that
    derivative turns, to O((w dt)^3), not at the nearest sample.
    """
    rate = interpolate.CubicHermiteSpline(time, np.unwrap(angle), speed).derivative()
    turning = rate.derivative().roots(extrapolate=False)
    high, low = np.empty(starts.size), np.empty(starts.size)
    for index, (start, end) in enumerate(zip(starts, ends)):
        inside = np.concatenate([[start, end], turning[(turning > start) & (turning < end)]])
        values = np.concatenate([rate(inside), speed[(time > start) & (time < end)]])
        high[index], low[index] = np.max(values), np.min(values)
    return high, low


def _measured_and_theory(row: Dict[str, Any], name: str, values: np.ndarray,
                         theory: Optional[float]) -> None:
    """Put a figure's mean and spread over pairs, its theory and relative error in row."""
    mean, spread = _mean_and_spread(values)
    row[f'{name}_measured'] = mean
    row[f'{name}_measured_std'] = spread
    row[f'{name}_theory'] = finite_or_none(theory)
    row[f'{name}_relative_error'] = (None if mean is None or row[f'{name}_theory'] is None
                                     else _relative_error(mean, row[f'{name}_theory']))


def _not_recorded(samples: Samples) -> np.ndarray:
    return np.full(samples.time.shape, np.nan)


def measure_segment(samples: Samples, segment: Segment, geometry: kin.Geometry,
                    drive: Optional[Drive] = None) -> Dict[str, Any]:
    """Measured and theoretical figures of one steady segment, as a JSON-ready dict."""
    span = slice(segment.start, segment.end)
    misplaced = misplaced_stamps(samples.time[span], samples.input_angle[span],
                                 samples.input_speed[span])
    misplaced_times = samples.time[span][misplaced].tolist()
    if misplaced.any():  # measured without them, and said (report.misplaced_stamp_lines)
        kept = np.flatnonzero(~misplaced) + segment.start
        samples = Samples._make(None if values is None else values[kept] for values in samples)
        span = slice(0, kept.size)
    pairs = find_stroke_pairs(samples.time[span], samples.ram_position[span],
                              samples.ram_velocity[span])
    row: Dict[str, Any] = {
        'offset': segment.offset,
        'offset_over_pivot_distance': segment.offset / geometry.pivot_distance,
        'input_speed': segment.input_speed,
        'start_time': float(samples.time[span][0]),
        'end_time': float(samples.time[span][-1]),
        'misplaced_stamps': misplaced_times,
        'stroke_pairs': int(len(pairs.time_ratio)),
        'samples_per_revolution': None,
    }
    if segment.input_speed != 0.0:
        step = float(np.median(np.diff(samples.time[span])))
        row['samples_per_revolution'] = 2 * math.pi / (abs(segment.input_speed) * step)
    measured = {
        'time_ratio': pairs.time_ratio, 'speed_ratio': pairs.speed_ratio,
        'peak_speed_ratio': pairs.peak_speed_ratio, 'cutting_time': pairs.cutting_time,
        'return_time': pairs.return_time, 'peak_cutting_speed': pairs.peak_cutting_speed,
        'peak_return_speed': pairs.peak_return_speed}
    theory: Dict[str, Any] = {name: None for name in measured}
    if segment.input_speed != 0.0 and abs(segment.offset) < geometry.coupling_radius:
        with contextlib.suppress(kin.KinematicsError):  # e.g. a speed too large to be finite
            theory.update(kin.steady_theory(geometry, segment.offset,
                                            segment.input_speed)._asdict())
    for name, values in measured.items():
        _measured_and_theory(row, name, values, theory[name])
    edges, efforts = _measure_efforts(row, samples, span, pairs, geometry, drive)
    per_pair = _add_sampling_bounds(row, samples, span, pairs, geometry, drive, edges)
    _leave_out_unsupported_efforts(row, efforts, per_pair)
    return row


# Figures that are work done, whose theory is 0 without loads.
_WORK_FIGURES = ('energy_per_pair', 'mean_input_power')


def relative_bound(row: Dict[str, Any], name: str, bound: Optional[float]) -> Optional[float]:
    """
    Return a sampling bound of a figure of row over its theory (its measured value if none).

    A bound of 0 is 0 whatever the figure; a work or power whose theory is 0 (no loads) is
    compared with the work the RMS torque would do over the pair (or its power).
    """
    reference = row.get(f'{name}_theory') or row.get(f'{name}_measured')
    if bound == 0.0:
        return 0.0
    if row.get(f'{name}_theory') == 0.0 and name in _WORK_FIGURES:
        rms = row.get('rms_input_torque_theory') or 0.0
        reference = rms * (2 * math.pi if name == 'energy_per_pair'
                           else abs(row['input_speed']))
    if bound is None or not reference:
        return None
    return bound / abs(reference)


def _leave_out_unsupported_efforts(row: Dict[str, Any], efforts: Any,
                                   per_pair: List[Dict[str, Optional[float]]]) -> None:
    """
    Take the effort figures over the pairs whose sampling supports them, if any does.

    A late or lost sample at a sharp peak can leave one pair's efforts unsupported to
    SUPPORTED_RELATIVE_ERROR while its neighbours' are: the segment's effort figures are
    then the means over those, and row says how many pairs were left out. If no pair's
    efforts are supported, all stay in and their bound says so (exit 3).
    """
    row['stroke_pairs_left_out_of_efforts'] = 0
    finite = np.isfinite(efforts.energy_per_pair)
    supported = finite & np.array([all(
        (relative := relative_bound(row, name, found[name])) is not None
        and relative <= SUPPORTED_RELATIVE_ERROR for name in EFFORT_FIGURES)
        for found in per_pair], dtype=bool)
    if not supported.any() or supported.sum() == finite.sum():
        return
    row['stroke_pairs_left_out_of_efforts'] = int(finite.sum() - supported.sum())
    for name in EFFORT_FIGURES:
        kept = np.where(supported, getattr(efforts, name), np.nan)
        _measured_and_theory(row, name, kept, row[f'{name}_theory'])
        row[f'{name}_sampling_bound'] = float(np.mean(
            [found[name] for found, used in zip(per_pair, supported) if used]))
    for name in ZERO_CAN_BE_EXACT:
        if name in EFFORT_FIGURES:
            mean, expected = row[f'{name}_measured'], row[f'{name}_theory']
            row[f'{name}_absolute_error'] = (None if mean is None or expected is None
                                             else mean - expected)


class _EffortBounds:
    """
    The effort figures' bounds of one segment (core.measurement.effort_sampling_bounds), per pair.

    Only the ideal speed drive's efforts are bounded (its theory is exact); the motor's
    steady running is simulated, so its figures have none. A constant recorded speed
    (the speed drive, or a file older than the drive parameters) measures Cs exactly: 0.
    """

    def __init__(self, row: Dict[str, Any], constant: bool, geometry: kin.Geometry,
                 drive: Optional[Drive], speed: float, motion: Any) -> None:
        """constant: the segment's recorded input speed is one value throughout."""
        self.fluctuation = 0.0 if constant and (drive is None or drive.motor is None) else None
        self.theory = {name: row.get(f'{name}_theory') for name in EFFORT_FIGURES}
        self.efforts = None
        if drive is not None and drive.motor is None and motion is not None:
            self.efforts = steady_efforts(geometry, drive.mass, drive.loads, row['offset'],
                                          speed)
        self.motion, self.speed = motion, speed
        self._shifts: Dict[float, Optional[float]] = {}

    def at_step(self, step: float, interval_steps: Any = None) -> Dict[str, Optional[float]]:
        """Return the bounds at a longest step (s), or at one pair's own (interval_steps)."""
        found = effort_sampling_bounds(self.efforts, self.motion, self.theory, self.speed,
                                       step, interval_steps)
        found['speed_fluctuation'] = self.fluctuation
        return found

    def for_pair(self, step: float, bounds: Dict[str, Optional[float]], time: np.ndarray,
                 start: float, switches: np.ndarray) -> Dict[str, Optional[float]]:
        """
        Return one pair's bounds: its own steps' if they differ, none if a switch is unsure.

        step (s): the pair's longest step, rounded up; bounds: at that step; time: the
        pair's samples; start (s): its first reversal; switches (s): its reversals and the
        workpiece edges found in it.
        """
        steps = np.diff(time)
        if steps.size == 0 or self.efforts is None:
            return bounds
        if np.max(steps) > _IRREGULAR_STEPS * np.median(steps):
            bounds = {**bounds, **self.at_step(float(np.max(steps)),
                                               (time[:-1] - start, steps))}
        if step not in self._shifts:
            self._shifts[step] = switch_shift(self.efforts, self.motion, self.speed, step)
        shift = self._shifts[step]
        if shift is None or np.min(np.abs(time[:, None] - switches[None, :])) <= shift:
            bounds = {**bounds, **dict.fromkeys(EFFORT_FIGURES)}
        return bounds


# Why a segment whose input speed varies has no sampling bound (the JSON's
# sampling_bound_problem): a higher rate does not give one.
VARYING_SPEED = ('the input speed varies within the segment (the motor drive): the sampling '
                 'bounds hold at a constant input speed, and no bound is worked out for a '
                 'varying one')


def _add_sampling_bounds(row: Dict[str, Any], samples: Samples, span: slice, pairs: Any,
                         geometry: kin.Geometry, drive: Optional[Drive] = None,
                         edges: Optional[np.ndarray] = None
                         ) -> List[Dict[str, Optional[float]]]:
    """
    Add each figure's bound from the sampling alone (core.measurement.sampling_bounds), or None.

    Each pair is bounded at its own longest step (a late sample spoils only its pair), and
    the mean over the pairs by the mean of their bounds; steps are rounded up to 1 % so
    that a long run needs only a few bounds worked out. The effort figures likewise
    (core.measurement.effort_sampling_bounds). Return each pair's bounds.
    """
    time = samples.time[span]
    edges = np.empty(0) if edges is None else edges
    recorded = np.abs(samples.input_speed[span])
    fastest = max(abs(row['input_speed']), float(np.max(recorded)) if recorded.size else 0.0)
    speed = math.copysign(fastest, row['input_speed'])
    motion = steady_motion(geometry, row['offset']) if fastest > 0.0 else None
    theory = None
    # The kinematic bounds take the motion at a constant input speed: a speed that varies
    # within the segment (a motor, whose speed drops at each load switch and so bends the
    # ram's motion there) has none.
    varies = bool(recorded.size) and not bool(np.all(recorded == recorded[0]))
    row['sampling_bound_problem'] = VARYING_SPEED if varies else None
    if motion is not None and not varies:
        with contextlib.suppress(kin.KinematicsError):
            theory = kin.steady_theory(geometry, row['offset'], speed)
    steps = np.array([np.max(np.diff(time[first:last + 1]), initial=0.0)
                      for first, last in zip(pairs.first_sample, pairs.last_sample)])
    rounded = step_on_grid(steps)  # a step of 0 s gets no bound
    effort_bounds = _EffortBounds(row, bool(recorded.size) and not varies, geometry, drive,
                                  speed, motion)
    per_step = {step: {**(figure_sampling_bounds(geometry, row['offset'], speed, step, motion,
                                                 theory) if theory is not None
                          else dict.fromkeys(BOUNDED_FIGURES)), **effort_bounds.at_step(step)}
                for step in np.unique(rounded)}
    per_pair = [effort_bounds.for_pair(
        step, per_step[step], time[first:last + 1], start,
        np.concatenate([[start, middle, end], edges[(edges > start) & (edges < end)]]))
        for step, first, last, start, middle, end in zip(
            rounded, pairs.first_sample, pairs.last_sample, pairs.cutting_start,
            pairs.cutting_end, pairs.return_end)]
    for name in ALL_BOUNDED_FIGURES:
        bounds = [found[name] for found in per_pair]
        known = [bound for bound in bounds if bound is not None]
        row[f'{name}_sampling_bound'] = (float(np.mean(known)) if known and len(known) ==
                                         len(bounds) else None)
    return per_pair


def _measure_efforts(row: Dict[str, Any], samples: Samples, span: slice, pairs: Any,
                     geometry: kin.Geometry, drive: Optional[Drive]
                     ) -> Tuple[Optional[np.ndarray], Any]:
    """
    Add the drive's figures per pair (efforts, speed fluctuation, flywheel swing) to row.

    Return the workpiece edges found (s; None without the recorded loads) and the pairs'
    efforts (strokes.PairEffortsMeasured).
    """
    time = samples.time[span]
    torque = samples.input_torque if samples.input_torque is not None else _not_recorded(
        samples)
    force = samples.offset_force if samples.offset_force is not None else _not_recorded(
        samples)
    # Piece by piece where the sampling can be bounded (the ideal speed drive); the motor's
    # efforts, which have no bound, are measured as before (linear between samples).
    edges = None if drive is None or drive.motor is not None else workpiece_edge_times(
        time, samples.ram_position[span], samples.ram_velocity[span], pairs.cutting_start,
        pairs.cutting_end, drive.loads.cutting_length)
    measured = measure_pair_efforts(time, samples.input_speed[span], torque[span], force[span],
                                    pairs, edges)
    row['stroke_pairs_with_efforts'] = int(np.count_nonzero(
        np.isfinite(measured.energy_per_pair)))
    theory, row['effort_theory_problem'] = (
        (dict.fromkeys(THEORY_FIGURES), None) if drive is None
        else steady_effort_theory_and_problem(Setting(geometry, drive.mass, drive.loads,
                                                      drive.motor, row['offset'],
                                                      row['input_speed'])))
    for name in EFFORT_FIGURES:
        _measured_and_theory(row, name, getattr(measured, name), theory[name])
    _measured_and_theory(row, 'speed_fluctuation', measured.speed_fluctuation,
                         theory['speed_fluctuation'])
    for name in ZERO_CAN_BE_EXACT:
        mean, expected = row[f'{name}_measured'], row[f'{name}_theory']
        row[f'{name}_absolute_error'] = (None if mean is None or expected is None
                                         else mean - expected)
    swing = np.empty(0)
    if pairs.cutting_start.size:
        high, low = _speed_extremes(time, samples.flywheel_angle[span],
                                    samples.flywheel_speed[span], pairs.cutting_start,
                                    pairs.return_end)
        # The flywheel turns one way within a pair (w2 / w1 > 0), so |max| / |min| is it.
        swing = np.maximum(np.abs(high), np.abs(low)) / np.minimum(np.abs(high), np.abs(low))
    swing_theory = (flywheel_speed_swing(geometry, row['offset'])
                    if abs(row['offset']) < geometry.coupling_radius else None)
    _measured_and_theory(row, 'flywheel_speed_swing', swing, swing_theory)
    return edges, measured


def segment_geometry(geometry: kin.Geometry, segment: Segment) -> kin.Geometry:
    """Return the recording's geometry with the segment's recorded crank radius, if any."""
    radius = segment.crank_radius
    if radius is None or radius == geometry.crank_radius or not (
            0.0 < radius < geometry.pivot_distance):
        return geometry
    return dataclasses.replace(geometry, crank_radius=radius)


def with_stroke(row: Dict[str, Any], segment: Segment,
                geometry: kin.Geometry) -> Dict[str, Any]:
    """Add the segment's crank radius and stroke (recordings with the crank radius joint)."""
    if segment.crank_radius is not None:
        row['crank_radius'] = segment.crank_radius
        row['stroke_length'] = finite_or_none(
            float(segment_geometry(geometry, segment).ram_stroke))
    return row


class Analysis(NamedTuple):
    recording: Recording
    segments: List[Segment]
    rows: List[Dict[str, Any]]
    transitions: List[Dict[str, Any]]


def analyse(recording: Recording) -> Analysis:
    """Segment the recording and measure every segment against the closed form."""
    with np.errstate(all='ignore'):  # absurd recorded values give inf/NaN, reported as null
        segments, transitions = split_segments(recording.samples, recording.drive_spans())
        rows = [with_stroke(measure_segment(recording.samples, s,
                                            segment_geometry(recording.geometry, s),
                                            s.drive), s, recording.geometry)
                for s in segments]
    return Analysis(recording, segments, rows, transitions)
