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
The motor stepper's integration within one segment: DOP853 steps, a few ahead of the stamps.

scipy's DOP853 (8th order) on the segment's right-hand side, its vector algebra written
out (core.numerics.portable_dop853: the same steps on every CPU). Each step's
dense output is sampled for a switch of the segment's mode; a switch inside a step is found
with brentq and the step is cut there, the next segment to start from it once the stamps
pass it. Steps are taken a few at a time ahead of the stamps (the same steps, so the same
numbers); their pieces of trajectory are handed out in order.
"""

import collections
from typing import Any, Callable, Deque, List, Optional, Tuple

import numpy as np
from scipy import optimize

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.motor.motor_segment import SegmentFunctions
from qrm_ros.core.numerics.portable_dop853 import PortableDop853

__all__ = ['ATOL', 'Dop853', 'float_dense', 'Piece', 'ROOT_SAMPLES', 'RTOL',
           'SegmentIntegration', 'STEPS_AHEAD']

# The integrator's tolerances (DOP853, 8th order): the state is (rad, rad/s).
RTOL = 1e-12
ATOL = 1e-12
# Dense-output samples per step when looking for a switch inside it (a function that goes
# out and back within one fifth of a step would be missed; steps are far shorter than the
# load pieces).
ROOT_SAMPLES = 5
# Solver steps taken at once, ahead of the stamps (within the segment: a switch ends them; a
# command or a reset drops what is ahead): the same steps, so the same numbers, run back to
# back about every 10 ticks at 1 kHz. In a running node each step then costs less than alone
# between two ticks (warm caches): the motor node's CPU fell from 1.36-1.51 to 1.21-1.34
# times the speed drive's in two interleaved runs against one step at a time. Sixteen cut it
# further, but their bursts made 1.8 % of the 1 kHz ticks missed (four or six: as the speed
# drive, about 0.2-0.4 %).
STEPS_AHEAD = 4

# A piece of trajectory: (start s, end s, time -> (angle, speed) on it).
Piece = Tuple[float, float, Callable[[float], Tuple[float, float]]]
# Called with (start, end, scipy's dense output) of every piece as it is made.
Observer = Callable[[float, float, Any], None]


def float_dense(dense: Any) -> Callable[[float], Tuple[float, float]]:
    """
    Return time (s) -> (angle, speed) on a DOP853 step's dense output, in plain floats.

    The same operations in the same order as scipy's Dop853DenseOutput (Horner in x and
    1 - x over its rows F, then y_old added), so the same numbers bit for bit, without
    numpy's cost per call (about 9 us a call, most of a tick's output).
    """
    t_old, h = float(dense.t_old), float(dense.h)
    rows = dense.F.tolist()
    (a0, s0), (a1, s1), (a2, s2), (a3, s3), (a4, s4), (a5, s5), (a6, s6) = rows
    angle_old, speed_old = dense.y_old.tolist()

    def at(time):
        x = (time - t_old) / h
        w = 1 - x
        return ((((((((0.0 + a6) * x + a5) * w + a4) * x + a3) * w + a2) * x + a1) * w + a0)
                * x + angle_old,
                (((((((0.0 + s6) * x + s5) * w + s4) * x + s3) * w + s2) * x + s1) * w + s0)
                * x + speed_old)
    return at


class Dop853(PortableDop853):
    """DOP853 at the stepper's tolerances, its steps the same on every CPU."""

    def __init__(self, rhs: Callable, time: float, state: List[float], bound: float) -> None:
        super().__init__(rhs, time, state, bound, rtol=RTOL, atol=ATOL)


class SegmentIntegration:
    """
    One segment's solver, its pieces made ahead of the stamps, and the switch that ends it.

    ``next_piece`` hands out the segment's pieces of trajectory in order, stepping the solver
    when none is left; None once the segment is over, and ``restart`` then says where the
    next one starts. observer, if set, sees every piece as it is made (speed_fluctuation's
    exact extremes).
    """

    def __init__(self, functions: SegmentFunctions, time: float, angle: float, speed: float,
                 bound: float, spin: int, observer: Optional[Observer]) -> None:
        self._functions = functions
        self._solver = Dop853(functions.rhs, time, [angle, speed], bound)
        self._spin = spin
        self.observer = observer
        # Pieces made ahead of the stamps, in order: (start, end, float dense).
        self._ahead: Deque[Piece] = collections.deque()
        # A switch found in the last step, its segment not started yet: (time, angle, speed,
        # kind) once the stamps pass it.
        self._pending: Optional[Tuple[float, float, float, int]] = None

    def next_piece(self) -> Optional[Piece]:
        """Return the next piece of the segment, or None once it is over (see restart)."""
        ahead = self._ahead
        if ahead:
            return ahead.popleft()
        solver = self._solver
        if self._pending is not None or solver.status == 'finished':
            return None
        for _ in range(STEPS_AHEAD):
            ahead.append(self._step(solver))
            if self._pending is not None or solver.status == 'finished':
                break
        return ahead.popleft()

    def restart(self) -> Tuple[float, float, float, Optional[int]]:
        """
        Return where the next segment starts: (time, angle, speed, switch kind or None).

        The switch found, or, with none, the solver's bound (a ramp's end).
        """
        if self._pending is not None:
            return self._pending
        angle, speed = self._solver.y.tolist()
        return float(self._solver.t), angle, speed, None

    def _step(self, solver: Dop853) -> Piece:
        """Take one solver step; return its piece (cut at a switch, then pending)."""
        message = solver.step()
        if solver.status == 'failed':
            raise dyn.DynamicsError(f'the motor-drive integration failed: {message}')
        # Plain floats (numpy's scalars are several times slower in the arithmetic below).
        start, end = float(solver.t_old), float(solver.t)
        dense = solver.dense_output()
        at = float_dense(dense)
        switch = self._first_switch(at, start, end)
        if switch is None:
            if self.observer is not None:
                self.observer(start, end, dense)
            return start, end, at
        time, kind = switch
        if self.observer is not None:
            self.observer(start, time, dense)
        angle, speed = at(time)
        self._pending = (time, angle, speed, kind)
        return start, time, at

    def _first_switch(self, at, start, end):
        """Return (time, kind) of the first switch in the step from start to end (s), or None."""
        # np.linspace(start, end, ROOT_SAMPLES + 1), the same numbers without its overhead.
        step = (end - start) / ROOT_SAMPLES
        times = [index * step + start for index in range(ROOT_SAMPLES)] + [end]
        samples = [at(time) for time in times]
        angles, speeds = zip(*samples)
        # With the speed's sign held at every sample, the ram's switching functions change
        # sign only at the load's switch angles.
        low, high = min(speeds), max(speeds)
        held = low > 0.0 if self._spin > 0 else high < 0.0
        ram = not (held and self._functions.clear(min(angles), max(angles)))
        if not ram and self._functions.motor_holds(start, low, high):
            return None  # no switching function goes from > 0 to <= 0 between samples
        switching = self._functions.switching
        previous = switching(times[0], *samples[0], ram)
        for index in range(1, len(times)):
            values = switching(times[index], *samples[index], ram)
            if min(values) > 0.0:  # the mode holds at this sample: nothing switched before it
                previous = values
                continue
            found = []
            for kind, (before, after) in enumerate(zip(previous, values)):
                if before > 0.0 and after <= 0.0:
                    if after == 0.0:
                        found.append((times[index], kind))
                        continue

                    def value(time, kind=kind):
                        return switching(time, *at(time))[kind]
                    root = optimize.brentq(value, times[index - 1], times[index],
                                           xtol=1e-15, rtol=4 * np.finfo(float).eps)
                    found.append((root, kind))
            if found:
                return min(found)
            previous = values
        return None
