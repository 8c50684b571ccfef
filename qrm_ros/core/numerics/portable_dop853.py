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
scipy's DOP853 with its vector algebra written out: the same steps on every CPU.

scipy's Runge-Kutta steps combine the stages with np.dot and measure the error with
np.linalg.norm, which numpy hands to BLAS; OpenBLAS picks its kernel by the CPU (fused
multiply-adds or not, the terms in another order), so the last bits of a stage, of the error
norm and so of every step size depended on the machine. Here the method is still scipy's
(its class, tableau, step-size controller, initial step, dense output), and every
combination is a sum of products added left to right (core.numerics.fixed_order) in plain floats.
Two other choices keep libm out of the controller: the error norm's square is the sum of
squares (not the norm squared by pow), and the step factor err^(-1/8) is
1 / sqrt(sqrt(sqrt(err))) (IEEE's sqrt is correctly rounded; libm's pow is not, and picks
its code by the CPU too). Zero coefficients of the tableau are skipped.
"""

import math
from typing import Callable, List, Sequence, Tuple

import numpy as np
from scipy import integrate
# The step-size controller's constants, scipy's own (not part of its public API).
from scipy.integrate._ivp.rk import Dop853DenseOutput, MAX_FACTOR, MIN_FACTOR, SAFETY

from qrm_ros.core.numerics.fixed_order import weighted_sum

__all__ = ['PortableDop853']

# (time, state as a list of floats) -> its derivative as a list of floats.
RightHandSide = Callable[[float, List[float]], Sequence[float]]
# A row of the tableau without its zeros: (stage indices, coefficients).
Row = Tuple[Tuple[int, ...], Tuple[float, ...]]


def _row(coefficients) -> Row:
    kept = [(index, float(value)) for index, value in enumerate(coefficients) if value != 0.0]
    return tuple(index for index, _ in kept), tuple(value for _, value in kept)


def _combined(stages: List[List[float]], row: Row) -> List[float]:
    """Per component, the row's stages times its coefficients, added left to right."""
    indices, weights = row
    return [weighted_sum([stages[index][component] for index in indices], weights)
            for component in range(len(stages[0]))]


def _eighth_root(value: float) -> float:
    return math.sqrt(math.sqrt(math.sqrt(value)))


class PortableDop853(integrate.DOP853):
    """
    scipy's DOP853 whose every step has the same bits on every CPU (module docstring).

    rhs(time, state) takes the state as a list of floats and returns its derivative as a
    sequence of floats; it is called directly, without scipy's wrappers (nfev is not
    counted). The state and the dense output are scipy's numpy arrays as usual.
    """

    _STAGES = tuple(_row(a[:s]) for s, a in enumerate(integrate.DOP853.A) if s > 0)
    _SOLUTION = _row(integrate.DOP853.B)
    _ERROR5 = _row(integrate.DOP853.E5)
    _ERROR3 = _row(integrate.DOP853.E3)
    _EXTRA = tuple(_row(a[:s]) for s, a in enumerate(
        integrate.DOP853.A_EXTRA, start=integrate.DOP853.n_stages + 1))
    _INTERPOLATION = tuple(_row(row) for row in integrate.DOP853.D)
    _NODES = tuple(float(node) for node in integrate.DOP853.C)
    _EXTRA_NODES = tuple(float(node) for node in integrate.DOP853.C_EXTRA)

    def __init__(self, rhs: RightHandSide, time: float, state: Sequence[float], bound: float,
                 rtol: float, atol: float) -> None:
        state = [float(value) for value in state]
        derivative = [float(value) for value in rhs(time, state)]
        first_step = self._initial_step(rhs, time, state, derivative, bound, rtol, atol)
        super().__init__(lambda t, y: rhs(t, y.tolist()), time, state, bound, rtol=rtol,
                         atol=atol, first_step=first_step if first_step > 0.0 else None)
        self.fun = rhs
        self._state = state
        self._derivative = derivative
        self._stages: List[List[float]] = [derivative] * (self.n_stages + 4)

    def _initial_step(self, rhs, time, state, derivative, bound, rtol, atol):
        """Return the first step (s) as scipy's select_initial_step does, its norms written out."""
        length = abs(bound - time)
        if length == 0.0:
            return 0.0
        direction = 1.0 if bound >= time else -1.0
        scale = [atol + abs(value) * rtol for value in state]
        d0 = self._rms([value / weight for value, weight in zip(state, scale)])
        d1 = self._rms([value / weight for value, weight in zip(derivative, scale)])
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, length)
        moved = [value + h0 * direction * rate for value, rate in zip(state, derivative)]
        again = rhs(time + h0 * direction, moved)
        d2 = self._rms([(after - before) / weight for after, before, weight
                        in zip(again, derivative, scale)]) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = _eighth_root(0.01 / max(d1, d2))  # order 7: (...)^(1/8)
        return min(100 * h0, h1, length)  # max_step: none (inf)

    @staticmethod
    def _rms(values: List[float]) -> float:
        return math.sqrt(weighted_sum(values, values) / len(values))

    def _step_impl(self):
        """Take one step as scipy's RungeKutta._step_impl does, on lists."""
        t = float(self.t)
        direction = float(self.direction)
        min_step = 10 * abs(math.nextafter(t, direction * math.inf) - t)
        if self.h_abs > self.max_step:
            h_abs = self.max_step
        elif self.h_abs < min_step:
            h_abs = min_step
        else:
            h_abs = self.h_abs
        rejected = False
        while True:
            if h_abs < min_step:
                return False, self.TOO_SMALL_STEP
            t_new = t + h_abs * direction
            if direction * (t_new - self.t_bound) > 0:
                t_new = self.t_bound
            h = t_new - t
            h_abs = abs(h)
            state_new, derivative_new = self._rk_step(t, h)
            scale = [self.atol + max(abs(before), abs(after)) * self.rtol
                     for before, after in zip(self._state, state_new)]
            error_norm = self._error_norm(h, scale)
            if error_norm < 1:
                factor = (MAX_FACTOR if error_norm == 0
                          else min(MAX_FACTOR, SAFETY / _eighth_root(error_norm)))
                if rejected:
                    factor = min(1, factor)
                h_abs *= factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY / _eighth_root(error_norm))
            rejected = True
        self.h_previous = h
        self.y_old = self.y
        self._state_old, self._derivative_old = self._state, self._derivative
        self.t = t_new
        self._state, self._derivative = state_new, derivative_new
        self.y = np.array(state_new)
        self.h_abs = h_abs
        self.f = np.array(derivative_new)
        return True, None

    def _rk_step(self, t, h):
        """Return the new state and derivative as scipy's rk_step, in the tableau's order."""
        stages, state, rhs = self._stages, self._state, self.fun
        stages[0] = self._derivative
        for s, row in enumerate(self._STAGES, start=1):
            step = _combined(stages, row)
            stages[s] = rhs(t + self._NODES[s] * h,
                            [value + change * h for value, change in zip(state, step)])
        solution = _combined(stages, self._SOLUTION)
        state_new = [value + h * change for value, change in zip(state, solution)]
        derivative_new = rhs(t + h, state_new)
        stages[self.n_stages] = derivative_new
        return state_new, derivative_new

    def _error_norm(self, h, scale):
        """DOP853's error norm (Hairer's mix of the 5th- and 3rd-order estimates)."""
        error5 = [value / weight for value, weight
                  in zip(_combined(self._stages, self._ERROR5), scale)]
        error3 = [value / weight for value, weight
                  in zip(_combined(self._stages, self._ERROR3), scale)]
        square5 = weighted_sum(error5, error5)
        square3 = weighted_sum(error3, error3)
        if square5 == 0 and square3 == 0:
            return 0.0
        denominator = square5 + 0.01 * square3
        return abs(h) * square5 / math.sqrt(denominator * len(scale))

    def _dense_output_impl(self):
        """Return the step's dense output as scipy's DOP853: three more stages, then its rows."""
        stages, h, t_old = self._stages, self.h_previous, float(self.t_old)
        state_old = self._state_old
        for s, row in enumerate(self._EXTRA, start=self.n_stages + 1):
            step = _combined(stages, row)
            stages[s] = self.fun(t_old + self._EXTRA_NODES[s - self.n_stages - 1] * h,
                                 [value + change * h for value, change in zip(state_old, step)])
        first, last = self._derivative_old, self._derivative
        delta = [after - before for after, before in zip(self._state, state_old)]
        rows = [delta,
                [h * rate - change for rate, change in zip(first, delta)],
                [2 * change - h * (end + start) for change, start, end
                 in zip(delta, first, last)]]
        rows += [[h * value for value in _combined(stages, row)] for row in self._INTERPOLATION]
        return Dop853DenseOutput(t_old, self.t, self.y_old, np.array(rows))
