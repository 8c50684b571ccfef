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
The steady spans of a run: one offset, one stroke, one commanded input speed, one drive, no gap.

Only whole stroke pairs inside such a span are measured; what lies between two spans (a
ramp of the offset, a speed change, a load change, a pause or a clock jump) is a transition,
excluded from the measurement and reported.
"""

import math
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from qrm_ros.analysis.recorded_drive import Drive, drive_differences, DriveSpan
from qrm_ros.analysis.recorded_run import MIN_SEGMENT_SAMPLES, Samples
from qrm_ros.core.measurement.sampling_bounds import gap_after

# Samples whose offset and input speed differ by less than this (relative) are one setting.
STEADY_TOLERANCE = 1e-12
# A step between stamps longer than sampling_bounds.gap_after (three median sample periods,
# and 50 ms) is a gap (a pause, a clock jump, lost messages): segments end there, so no
# stroke is measured across it (the node's stroke-pair reports call a pair across one not
# steady, alike).


class Segment(NamedTuple):
    start: int  # sample indices, end exclusive
    end: int
    offset: float
    input_speed: float  # rad/s, commanded (setting_speed)
    drive: Optional[Drive] = None  # what drove it (None: no theory of the efforts)
    crank_radius: Optional[float] = None  # m, recorded (None: the metadata's geometry's)


def sample_period(samples: Samples) -> Optional[float]:
    """Return the median step between stamps (s), None with fewer than two samples."""
    steps = np.diff(samples.time)
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else None


def setting_speed(samples: Samples, drive: Optional[Drive] = None) -> np.ndarray:
    """
    Return the input speed each sample was commanded to run at (rad/s).

    The ideal speed drive runs at it. A motor's speed fluctuates about its reference, but
    its torque is k (reference - speed) (dynamics.md), so the reference is the recorded
    speed plus the recorded input torque over k, exact to round-off at every sample. Where
    the motor is at its torque limit the sample does not hold the reference: a span of such
    samples takes the reference of the samples on both its sides when the two agree (no
    command came in between), else it has none (NaN: no steady setting).
    """
    if drive is None or drive.motor is None or samples.input_torque is None:
        return samples.input_speed
    torque = samples.input_torque
    reference = samples.input_speed + torque / drive.motor.speed_stiffness
    limited = np.abs(torque) >= drive.motor.max_torque * (1.0 - STEADY_TOLERANCE)
    return _through_limits(np.where(limited, np.nan, reference))


def _through_limits(reference: np.ndarray) -> np.ndarray:
    """Fill each run of NaN whose neighbours on both sides agree with their value."""
    known = np.flatnonzero(~np.isnan(reference))
    if known.size < 2 or known.size == reference.size:
        return reference
    index = np.arange(reference.size)
    before = np.searchsorted(known, index, side='right') - 1  # the last known at or before
    inside = (before >= 0) & (before < known.size - 1)  # a known sample after too
    left = reference[known[np.clip(before, 0, known.size - 1)]]
    right = reference[known[np.clip(before + 1, 0, known.size - 1)]]
    agree = inside & (np.abs(left - right) <= STEADY_TOLERANCE * np.maximum(1.0, np.abs(left)))
    return np.where(np.isnan(reference) & agree, left, reference)


def setting_speeds(samples: Samples, drives: Sequence[DriveSpan]
                   ) -> Tuple[np.ndarray, np.ndarray]:
    """Return each sample's commanded input speed (rad/s) and the index of its drive span."""
    span = np.searchsorted([d.start_time for d in drives], samples.time, side='right') - 1
    span = np.maximum(span, 0)
    speed = np.empty(samples.time.shape)
    for index, drive in enumerate(drives):
        chosen = span == index
        speed[chosen] = setting_speed(samples, drive.drive)[chosen]
    return speed, span


def speed_scale(largest: float) -> float:
    """Return the scale of the speed tolerance, from the largest finite |speed| (rad/s)."""
    return max(1.0, largest)


def largest_speed(speed: np.ndarray) -> float:
    """Return the largest finite |speed| (rad/s); 0 when none is finite."""
    finite = np.abs(speed[np.isfinite(speed)])
    return float(np.max(finite)) if finite.size else 0.0


def setting_changes(time: np.ndarray, offset: np.ndarray, speed: np.ndarray, span: np.ndarray,
                    steady: np.ndarray, step: float, scale: float
                    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (steps, gap, boundary) between consecutive samples.

    steps: s between stamps; gap: the step is a gap (longer than gap_after of the usual step
    s, or backwards); boundary: a new run of one setting starts at the later sample.
    """
    steps = np.diff(time)
    gap = (steps > gap_after(step)) | (steps < 0)
    changed = ((np.abs(np.diff(offset)) > STEADY_TOLERANCE)
               | ~(np.abs(np.diff(speed)) <= STEADY_TOLERANCE * scale) | gap
               | (np.diff(span) != 0))
    return steps, gap, changed | (steady[1:] != steady[:-1])


def transition(before: Segment, after: Segment, start_time: float, end_time: float,
               largest_jump: Optional[float]) -> Dict[str, Any]:
    """
    Describe what lies between two segments (JSON-ready).

    largest_jump: the gap step between them of the largest size (s; < 0: the clock went
    back), None when none.
    """
    changes = []
    if largest_jump is not None:
        changes.append(f'a gap of {largest_jump:.3f} s between stamps (a pause, a clock jump '
                       'or lost messages)' if largest_jump > 0 else
                       f'the clock jumps back by {-largest_jump:.3f} s')
    if after.offset != before.offset:
        changes.append(f'offset {before.offset * 1e3:g} -> {after.offset * 1e3:g} mm')
    if after.crank_radius != before.crank_radius:
        changes.append(f'crank radius {(before.crank_radius or 0.0) * 1e3:g} -> '
                       f'{(after.crank_radius or 0.0) * 1e3:g} mm (a stroke change)')
    if after.input_speed != before.input_speed:
        changes.append(f'input speed {before.input_speed:g} -> {after.input_speed:g} rad/s')
    changes += drive_differences(before.drive, after.drive)
    return {
        'kind': 'gap' if largest_jump is not None else 'change',
        'start_time': start_time,
        'end_time': end_time,
        'offset_from': before.offset, 'offset_to': after.offset,
        'input_speed_from': before.input_speed, 'input_speed_to': after.input_speed,
        'change': ', '.join(changes) or 'interruption'}


def split_segments(samples: Samples, drives: Sequence[DriveSpan] = ()
                   ) -> Tuple[List[Segment], List[Dict[str, Any]]]:
    """
    Split into spans of steady offset and input speed; return (segments, transitions).

    A segment is a maximal run of samples that share one offset, one commanded input speed
    (setting_speed: under a motor, its speed reference) and one drive (drives: the masses,
    loads and drive from when on; none: the ideal speed drive, no theory) with the offset
    actuator at rest (a ramp changes the speed at every sample, so its samples never form a
    run) and no gap between stamps (longer than sampling_bounds.gap_after, or backwards: a
    pause, a clock jump, lost messages); what lies between segments is a transition,
    excluded from the measurement and reported.
    """
    drives = list(drives) or [DriveSpan(-math.inf, None, None)]
    offset, time = samples.offset, samples.time
    speed, span = setting_speeds(samples, drives)
    steady = samples.offset_rate == 0.0
    radius = samples.crank_radius
    if radius is not None and samples.crank_radius_rate is not None:
        steady = steady & (samples.crank_radius_rate == 0.0)  # the stroke screw still
    steps, gap, boundary = setting_changes(time, offset, speed, span, steady,
                                           sample_period(samples) or 0.0,
                                           speed_scale(largest_speed(speed)))
    if radius is not None:  # a stroke change splits as an offset change does
        boundary = boundary | (np.abs(np.diff(radius)) > STEADY_TOLERANCE)
    starts = np.flatnonzero(np.concatenate([[True], boundary]))
    ends = np.append(starts[1:], offset.size)
    segments = [Segment(int(a), int(b), float(offset[a]), float(speed[a]),
                        drives[span[a]].drive, None if radius is None else float(radius[a]))
                for a, b in zip(starts, ends) if steady[a] and b - a >= MIN_SEGMENT_SAMPLES]
    transitions = []
    for before, after in zip(segments, segments[1:]):
        jumps = steps[before.end - 1:after.start][gap[before.end - 1:after.start]]
        largest = float(jumps[np.argmax(np.abs(jumps))]) if jumps.size else None
        transitions.append(transition(before, after, float(time[before.end - 1]),
                                      float(time[after.start]), largest))
    return segments, transitions
