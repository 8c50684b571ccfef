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
Live per-stroke-pair measurement for the node's diagnostics, free of ROS.

The node feeds every published sample; when a cutting stroke begins, the pair before it is
complete and is measured with the same method as the offline analysis
(strokes.find_stroke_pairs) and compared with the core's theory for the offset and speed in
force. The node only wraps the returned reports in DiagnosticStatus messages. ``collect``
and ``measure`` split ``add`` in two, so a caller on a timer can measure later:
``collect`` only copies the completed samples, and ``measure_steps`` measures them a step
at a time between ticks. A sample's values are kept side by side in one typed array (one
call a tick) and measured as numpy rows of one copy of it, with no Python loop over the
samples: a 4000-sample pair takes 0.6 ms instead of 1.3.
"""

from array import array
import dataclasses
import math
from typing import Dict, List, NamedTuple, Optional

import numpy as np

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.measurement.sampling_bounds import gap_after
from qrm_ros.core.kinematics.steady_figures import steady_theory, SteadyTheory
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.core.measurement.strokes import (pair_effort_steps, PairEffortsMeasured, run_steps,
                                              Steps, stroke_pair_steps)

__all__ = ['BUFFER_LIMIT', 'CompletedSamples', 'MEASURED_FIGURES', 'PairReport', 'SAMPLE_FIELDS',
           'STROKE_SAMPLE_FIELDS', 'StrokeMonitor']

# At most this many samples wait for a stroke pair to end (at 100 Hz, 43 minutes; a shaft
# slower than one turn in that time gets no reports).
BUFFER_LIMIT = 2 ** 18
# StrokePairs fields reported per pair, in the order they are published.
MEASURED_FIGURES = ('cutting_time', 'return_time', 'time_ratio', 'peak_cutting_speed',
                    'peak_return_speed', 'mid_cutting_speed', 'mid_return_speed',
                    'speed_ratio', 'peak_speed_ratio', 'mean_cutting_speed'
                    ) + PairEffortsMeasured._fields
SAMPLE_FIELDS = ('ram_position', 'ram_velocity', 'offset', 'offset_rate', 'input_speed',
                 'input_torque', 'offset_force')
# Kept beside them: the crank radius in force and its rate (the stroke adjustment), and the
# speed the drive is set to (under a motor its speed reference: the speed itself fluctuates
# by nature, so a pair is steady in speed when the setting held).
STROKE_SAMPLE_FIELDS = ('crank_radius', 'crank_radius_rate', 'setting_speed')
_KEPT_FIELDS = SAMPLE_FIELDS + STROKE_SAMPLE_FIELDS
# The rows of the fields a steady pair holds at one value (the offset, the speed setting, the
# crank radius), and of the rates that are zero then (the offset's, the crank radius's).
_HELD_ROWS = [_KEPT_FIELDS.index(name) for name in ('offset', 'setting_speed', 'crank_radius')]
_RATE_ROWS = [_KEPT_FIELDS.index(name) for name in ('offset_rate', 'crank_radius_rate')]
_THEORY_CACHE_LIMIT = 64


class CompletedSamples(NamedTuple):
    """The samples of one or more completed stroke pairs, copied out of the buffer."""

    stamp_ns: int                 # the sample that completed the pair
    sample_stamps_ns: array       # 'q': node-clock ns, one per sample
    # 'd': per stamp, its values of SAMPLE_FIELDS + STROKE_SAMPLE_FIELDS in that order.
    sample_values: array


class PairReport(NamedTuple):
    """One completed stroke pair: what was measured, what theory says, and in what setting."""

    stamp_ns: int            # the sample that completed the pair
    pair_start: float        # s, on the sample clock
    pair_end: float          # s
    coupling_offset: float   # m, in force at the pair's end
    input_speed: float       # rad/s, in force at the pair's end
    offset_steady: bool      # the offset did not move during the pair
    input_speed_steady: bool  # the speed setting (a motor's reference) held during the pair
    measured: Dict[str, float]
    theory: Dict[str, float]  # empty at zero speed; keys end in '_theory'
    crank_radius: float = math.nan  # m, in force at the pair's end
    stroke_length: float = math.nan  # m, the ram stroke of that crank radius
    stroke_steady: bool = True  # the crank radius did not move during the pair
    # No gap in the samples during the pair (no step longer than sampling_bounds.gap_after).
    sampled_without_gap: bool = True

    @property
    def steady(self) -> bool:
        return (self.offset_steady and self.input_speed_steady and self.stroke_steady
                and self.sampled_without_gap)

    def values(self) -> Dict[str, float]:
        """Every figure as name -> float, in publishing order."""
        values = dict(self.measured)
        values.update(pair_start=self.pair_start, pair_end=self.pair_end,
                      coupling_offset=self.coupling_offset, input_speed=self.input_speed,
                      stroke_length=self.stroke_length, crank_radius=self.crank_radius)
        values.update(self.theory)
        return values


def theory_figures(theory_per_unit_speed: SteadyTheory, input_speed: float) -> Dict[str, float]:
    """Scale the theory at unit |speed| to a speed (times / |speed|, speeds x |speed|)."""
    unit, scale = theory_per_unit_speed, abs(input_speed)
    figures = {
        'time_ratio_theory': unit.time_ratio,
        'speed_ratio_theory': unit.speed_ratio,
        'peak_speed_ratio_theory': unit.peak_speed_ratio,
        'cutting_time_theory': unit.cutting_time / scale,
        'return_time_theory': unit.return_time / scale,
        'peak_cutting_speed_theory': unit.peak_cutting_speed * scale,
        'peak_return_speed_theory': unit.peak_return_speed * scale,
    }
    return {name: float(value) for name, value in figures.items()}  # one sample: floats


class StrokeMonitor:
    """Buffers samples and reports each stroke pair once it is complete."""

    def __init__(self, geometry: Geometry):
        self._geometry = geometry
        self._moved: Optional[Geometry] = None  # the latest other crank radius's geometry
        self._theory_cache: Dict[tuple, SteadyTheory] = {}
        self.clear()

    def clear(self) -> None:
        """Forget the samples (after a reset, a pause or a clock jump: no pair spans it)."""
        self._stamp_ns = array('q')
        # A sample's values side by side (_KEPT_FIELDS), one extend a tick.
        self._values = array('d')
        self._last_velocity_positive: Optional[bool] = None

    def __len__(self):
        return len(self._stamp_ns)

    def add(self, stamp_ns: int, ram_position: float, ram_velocity: float, offset: float,
            offset_rate: float, input_speed: float, input_torque: float,
            offset_force: float) -> List[PairReport]:
        """Take one sample; return the pairs it completed (usually none, at most a few)."""
        completed = self.collect(stamp_ns, ram_position, ram_velocity, offset, offset_rate,
                                 input_speed, input_torque, offset_force)
        return [] if completed is None else self.measure(completed)

    def collect(self, stamp_ns: int, ram_position: float, ram_velocity: float, offset: float,
                offset_rate: float, input_speed: float, input_torque: float,
                offset_force: float, crank_radius: Optional[float] = None,
                crank_radius_rate: float = 0.0, setting_speed: Optional[float] = None
                ) -> Optional[CompletedSamples]:
        """
        Take one sample; return the samples of the pairs it completed, to ``measure``.

        crank_radius (m; None: the geometry's) and its rate (m/s): the stroke in force;
        setting_speed (rad/s; None: input_speed): the speed the drive is set to.
        """
        self._stamp_ns.append(stamp_ns)
        if crank_radius is None:
            crank_radius = float(self._geometry.crank_radius)
        if setting_speed is None:
            setting_speed = input_speed
        self._values.extend((ram_position, ram_velocity, offset, offset_rate, input_speed,
                             input_torque, offset_force, crank_radius, crank_radius_rate,
                             setting_speed))
        if len(self._stamp_ns) > BUFFER_LIMIT:
            self._keep_from(len(self._stamp_ns) - BUFFER_LIMIT // 2)
        positive = ram_velocity >= 0.0
        # A cutting stroke beginning ends the pair before it: measure only then.
        completed = None
        if self._last_velocity_positive and not positive:
            completed = CompletedSamples(stamp_ns, array('q', self._stamp_ns),
                                         array('d', self._values))
            # Keep the two samples around the reversal just found: the next pair starts
            # there.
            self._keep_from(len(self._stamp_ns) - 2)
        self._last_velocity_positive = positive
        return completed

    def _keep_from(self, index):
        del self._stamp_ns[:index]
        del self._values[:index * len(_KEPT_FIELDS)]

    def measure(self, completed: CompletedSamples) -> List[PairReport]:
        """Measure the pairs in samples from ``collect`` and compare them with the theory."""
        return run_steps(self.measure_steps(completed))

    def measure_steps(self, completed: CompletedSamples) -> Steps[List[PairReport]]:
        """
        ``measure`` in steps (strokes.run_steps), each some tens of microseconds.

        A node's timer runs steps after each tick, in the time left before the next: a
        whole pair at once held a 4 kHz node's ticks back for its length, on a thread of its
        own too (the GIL). Touches no buffer, only the theory cache, so it may run between
        ``collect`` calls.
        """
        stamps = np.frombuffer(completed.sample_stamps_ns, dtype=np.int64)
        origin = int(stamps[0])
        # Exact differences, then one division each (float(ns - origin) / 1e9, as in Python).
        time = (stamps - origin) / NANOSECONDS_PER_SECOND
        # One contiguous row per field (one copy): the same values as a column of its own.
        rows = np.frombuffer(completed.sample_values).reshape(-1, len(_KEPT_FIELDS)).T.copy()
        columns = dict(zip(_KEPT_FIELDS, rows))
        # The usual step between samples (their median), to tell a gap in publication within
        # a pair. The steps are finite (whole ns apart), so the middle one of the sorted steps
        # (a + a is 2a: exact), or the sum of the middle two over 2, is np.median's value.
        steps = np.diff(time)
        middle = np.sort(steps)[(steps.size - 1) // 2:steps.size // 2 + 1].tolist()
        usual_step = (middle[0] + middle[-1]) / 2 if middle else math.inf
        yield
        pairs = yield from stroke_pair_steps(time, columns['ram_position'],
                                             columns['ram_velocity'])
        yield
        pair_efforts = yield from pair_effort_steps(
            time, columns['input_speed'], columns['input_torque'], columns['offset_force'],
            pairs)
        figures = {**pairs._asdict(), **pair_efforts._asdict()}
        reports = []
        for index in range(len(pairs.cutting_time)):
            yield
            reports.append(self._report(completed.stamp_ns, rows, origin, pairs, figures,
                                        index, (steps, usual_step)))
        return reports

    def _report(self, stamp_ns, rows, origin, pairs, figures, index, timing):
        first, last = int(pairs.first_sample[index]), int(pairs.last_sample[index])
        at_end = dict(zip(_KEPT_FIELDS, rows[:, last].tolist()))
        offset, speed = at_end['offset'], at_end['input_speed']
        radius = at_end['crank_radius']
        geometry = self._geometry_of(radius)
        # Whether each held field kept one value through the pair (min == max, nan: no), and
        # whether each rate was zero throughout: one reduction each for all of them.
        held = rows[_HELD_ROWS, first:last + 1]
        unmoved = (np.minimum.reduce(held, axis=1) == np.maximum.reduce(held, axis=1)).tolist()
        moving = rows[_RATE_ROWS, first:last].any(axis=1).tolist()
        origin_seconds = float(origin) / NANOSECONDS_PER_SECOND
        all_steps, usual_step = timing
        steps = all_steps[first:last]  # the pair's own steps
        return PairReport(
            stamp_ns=stamp_ns,
            pair_start=origin_seconds + float(pairs.cutting_start[index]),
            pair_end=origin_seconds + float(pairs.return_end[index]),
            coupling_offset=offset, input_speed=speed,
            offset_steady=unmoved[0] and not moving[0],
            input_speed_steady=unmoved[1],
            measured={name: float(figures[name][index]) for name in MEASURED_FIGURES},
            theory=self.theory(offset, speed, geometry) if speed != 0.0 else {},
            crank_radius=radius, stroke_length=float(geometry.ram_stroke),
            stroke_steady=unmoved[2] and not moving[1],
            sampled_without_gap=not steps.size or bool(
                np.maximum.reduce(steps) <= gap_after(usual_step)))

    def _geometry_of(self, crank_radius: float) -> Geometry:
        """Return the geometry with this crank radius (the same object while it holds)."""
        if crank_radius == self._geometry.crank_radius:
            return self._geometry
        if self._moved is None or self._moved.crank_radius != crank_radius:
            self._moved = dataclasses.replace(self._geometry, crank_radius=crank_radius)
        return self._moved

    def theory(self, offset: float, input_speed: float,
               geometry: Optional[Geometry] = None) -> Dict[str, float]:
        """Theory figures at a steady offset, speed and crank radius (geometry: the monitor's)."""
        geometry = geometry or self._geometry
        key = (offset, input_speed > 0.0, float(geometry.crank_radius))
        if key not in self._theory_cache:
            if len(self._theory_cache) > _THEORY_CACHE_LIMIT:
                self._theory_cache.clear()
            self._theory_cache[key] = steady_theory(geometry, offset,
                                                    math.copysign(1.0, input_speed))
        return theory_figures(self._theory_cache[key], input_speed)
