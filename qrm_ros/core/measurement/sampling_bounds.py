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
How far the sampling alone can move each measured stroke figure: a bound, not an estimate.

The stroke finder (core.measurement.strokes) puts a cubic Hermite interpolant through the sampled
ram positions and velocities. On an interval of length h its velocity differs from the true one
by at most sqrt(3)/216 h^3 max|x''''| and its position by at most h^4/384 max|x''''|
(Birkhoff and Priver's sharp constants). From these follow, with the motion's derivatives
taken from the closed form at a steady input speed, within two sample
intervals of each point: a peak speed moves by at most the
velocity bound; a reversal (the velocity's zero) by at most twice that bound over the
acceleration there, while the acceleration stays above half its value; a mid-stroke speed
(the ram at x = 0) by the velocity bound plus the acceleration times the crossing's shift;
ratios and stroke times by the worst combination of their parts. doc/analysis.md derives
them. Where a condition fails, or the motion is too sharp to work out its derivatives
within a bounded grid, the bound is None: the sampling supports no figure. numpy and scipy.ndimage.
"""

import math
from typing import Dict, List, NamedTuple, Optional, Tuple

import numpy as np
from scipy.ndimage import maximum_filter1d

from qrm_ros.core.kinematics.geometry import Geometry, TWO_PI
from qrm_ros.core.numerics.portable_math import log, power
from qrm_ros.core.kinematics.mechanism_state import (input_angle_for_flywheel_angle,
                                                     reversal_flywheel_angles, state)
from qrm_ros.core.kinematics.steady_figures import steady_theory, SteadyTheory

__all__ = ['BOUNDED_FIGURES', 'envelope', 'figure_sampling_bounds', 'FIRST_GRID', 'gap_after',
           'GAP_PERIODS', 'GAP_SECONDS', 'GRID_AGREEMENT', 'grid_reach', 'LAST_GRID', 'MARGIN',
           'spectral_derivative', 'step_on_grid', 'STEP_GRID_RATIO',
           'position_error_near', 'reversal_shifts', 'steady_motion', 'SteadyMotion',
           'SUPPORTED_RELATIVE_ERROR']

# A step between samples longer than this many median steps, and longer than GAP_SECONDS, is
# a gap (a pause, a stalled timer, ticks not published, a clock jump): no stroke pair is taken
# as steady across one (gap_after).
GAP_PERIODS = 3.0
# s: a shorter step is a late tick (a loaded machine's scheduler holds a timer back by up to
# tens of ms), not a stall; at 1 kHz three steps are 3 ms. A late sample widens the sampling
# bounds near it (they are taken at each pair's own steps), which is what it costs.
GAP_SECONDS = 0.05
# A figure whose sampling bound exceeds this fraction of it is not supported by the data.
SUPPORTED_RELATIVE_ERROR = 1e-3
# The measured figures given a sampling bound.
BOUNDED_FIGURES = ('time_ratio', 'speed_ratio', 'peak_speed_ratio', 'cutting_time',
                   'return_time', 'peak_cutting_speed', 'peak_return_speed',
                   'flywheel_speed_swing')
# Sharp constants of the cubic Hermite interpolant's error (position, velocity) / h^k f''''.
_POSITION_CONSTANT = 1.0 / 384.0
_VELOCITY_CONSTANT = math.sqrt(3.0) / 216.0
# Grids of one input revolution for the spectral derivatives: doubled until two agree.
FIRST_GRID, LAST_GRID = 1024, 1 << 17
GRID_AGREEMENT = 1e-3
# The grid's maxima are raised (its values at a reversal or a crossing lowered) by this
# factor: a maximum between grid points is not missed.
MARGIN = 1.05
# Steps are rounded up to a power of this before their bounds are worked out: a few
# distinct steps, each bounded once.
STEP_GRID_RATIO = 1.01


def step_on_grid(steps: np.ndarray) -> np.ndarray:
    """Round each step up to the next power of STEP_GRID_RATIO (0 stays 0); libm's log, pow."""
    return power(STEP_GRID_RATIO, np.ceil(log(steps) / math.log(STEP_GRID_RATIO)))


def gap_after(usual_step: float) -> float:
    """Return the step (s) beyond which a step between samples is a gap, at this usual step."""
    return max(GAP_PERIODS * usual_step, GAP_SECONDS)


class SteadyMotion(NamedTuple):
    """One input revolution at 1 rad/s on a grid: the derivatives the bounds need."""

    theta: np.ndarray  # input angle (rad), evenly spaced over [0, 2 pi)
    ram: Tuple[np.ndarray, ...]  # d^k x / dtheta^k for k = 0..4 (m/rad^k)
    flywheel_speed: np.ndarray  # dphi/dtheta
    flywheel_fourth: np.ndarray  # d4phi/dtheta4
    reversals: np.ndarray  # grid indices nearest the two reversals


def spectral_derivative(values: np.ndarray, order: int, roundoff: float = 0.0) -> np.ndarray:
    """
    Differentiate one period's samples (period 2 pi) order times, by FFT.

    roundoff: Fourier coefficients below this fraction of the largest are dropped first
    (the k^order of a high derivative would raise round-off above the signal); 0 keeps all.
    """
    spectrum = np.fft.rfft(values)
    if roundoff:
        # hypot of the parts: numpy's abs of a complex takes its own vector code where the
        # CPU has AVX-512 (other last bits, so other coefficients dropped); hypot does not.
        magnitude = np.hypot(spectrum.real, spectrum.imag)
        spectrum[magnitude < roundoff * np.max(magnitude)] = 0.0
    wave = 1j * np.arange(spectrum.size)
    return np.fft.irfft(spectrum * wave ** order, n=values.size)


def grid_reach(points: int, half_width: float, spacing: float) -> int:
    """Return the grid points either side that cover half_width (rad) at this spacing."""
    return min(points // 2, int(math.ceil(half_width / spacing)) + 1)


def envelope(values: np.ndarray, half_width: float, spacing: float) -> np.ndarray:
    """Return max |values| within half_width (rad) of each grid point, raised by MARGIN."""
    reach = grid_reach(values.size, half_width, spacing)
    return maximum_filter1d(np.abs(values), 2 * reach + 1, mode='wrap') * MARGIN


def _on_grid(geometry: Geometry, offset: float, points: int) -> SteadyMotion:
    theta = np.arange(points) * (TWO_PI / points)
    moving = state(geometry, offset, theta, 1.0)
    ram = np.asarray(moving.ram_position)
    # The flywheel turns with the input plus a bounded, periodic correction.
    flywheel = np.asarray(moving.flywheel_angle) - theta
    start, end = reversal_flywheel_angles(geometry)
    turns = np.mod(input_angle_for_flywheel_angle(geometry, offset, np.array([start, end])),
                   TWO_PI)
    return SteadyMotion(theta,
                        tuple(spectral_derivative(ram, k) if k else ram for k in range(5)),
                        1.0 + spectral_derivative(flywheel, 1),
                        spectral_derivative(flywheel, 4),
                        np.rint(turns / (TWO_PI / points)).astype(int) % points)


def _settled(before: SteadyMotion, after: SteadyMotion) -> bool:
    return all(abs(np.max(np.abs(a)) - np.max(np.abs(b))) <= GRID_AGREEMENT * np.max(np.abs(a))
               for a, b in ((after.ram[4], before.ram[4]),
                            (after.flywheel_fourth, before.flywheel_fourth)))


def steady_motion(geometry: Geometry, offset: float) -> Optional[SteadyMotion]:
    """
    Work out the motion over one input revolution at a steady offset; None if unresolved.

    The cost is bounded: grids of up to 131072 points (tens of ms), whatever the offset;
    an offset so close to the coupling radius that the fourth derivative does not settle
    on them gets None.
    """
    if not (math.isfinite(offset) and abs(offset) < geometry.coupling_radius):
        return None
    points, previous = FIRST_GRID, _on_grid(geometry, offset, FIRST_GRID)
    while True:
        points *= 2
        if points > LAST_GRID:
            return None
        current = _on_grid(geometry, offset, points)
        if _settled(previous, current):
            return current
        previous = current


def _ratio_bound(numerator: float, denominator: float, numerator_error: Optional[float],
                 denominator_error: Optional[float]) -> Optional[float]:
    """Largest change of numerator / denominator when each moves by up to its error."""
    if numerator_error is None or denominator_error is None or not (
            denominator_error < abs(denominator)):
        return None
    numerator, denominator = abs(numerator), abs(denominator)
    return ((numerator + numerator_error) / (denominator - denominator_error)
            - numerator / denominator)


class _Local:
    """Maxima of |a derivative| within a window of input angle around grid points."""

    def __init__(self, motion: SteadyMotion, half_width: float) -> None:
        self.points = motion.theta.size
        self.half_width, self.spacing = half_width, TWO_PI / self.points
        self.reach = grid_reach(self.points, half_width, self.spacing)

    def around(self, values: np.ndarray, index: int) -> float:
        picked = np.arange(index - self.reach, index + self.reach + 1) % self.points
        return float(np.max(np.abs(values[picked]))) * MARGIN

    def everywhere(self, values: np.ndarray) -> np.ndarray:
        return envelope(values, self.half_width, self.spacing)


def _extreme_shift(speed: np.ndarray, error: np.ndarray, where: np.ndarray,
                   highest: bool, reach: Optional[np.ndarray] = None) -> float:
    """
    How far the interpolant's extreme of speed over where can be from the true one.

    reach: where the interpolant's extreme may be taken from (default: where itself).
    """
    reach = where if reach is None else reach
    sign = 1.0 if highest else -1.0
    values, errors = sign * speed[where], error[where]
    top = int(np.argmax(values))
    return float(max(np.max(sign * speed[reach] + error[reach]) - values[top], errors[top]))


def figure_sampling_bounds(geometry: Geometry, offset: float, input_speed: float,
                           sample_interval: float, motion: Optional[SteadyMotion] = None,
                           theory: Optional[SteadyTheory] = None
                           ) -> Dict[str, Optional[float]]:
    """
    Bound of each figure of BOUNDED_FIGURES's error from the sampling, in its own unit.

    sample_interval (s): the longest step between samples; input_speed (rad/s): the
    recorded one (its largest |value| where it varies). None where the bound does not
    hold (see the module's docstring). motion and theory: steady_motion's and
    steady_theory's answers for these arguments, when already worked out.
    """
    bounds: Dict[str, Optional[float]] = dict.fromkeys(BOUNDED_FIGURES)
    if motion is None:
        motion = steady_motion(geometry, offset)
    if motion is None or not (math.isfinite(input_speed) and input_speed != 0.0
                              and math.isfinite(sample_interval) and sample_interval > 0.0):
        return bounds
    with np.errstate(all='ignore'):
        if theory is None:
            theory = steady_theory(geometry, offset, input_speed)
        _fill(bounds, theory, input_speed, sample_interval, motion)
    return {name: (None if value is None or not math.isfinite(value) else float(value))
            for name, value in bounds.items()}


def reversal_shifts(motion: SteadyMotion, input_speed: float,
                    sample_interval: float) -> List[Optional[float]]:
    """
    How far (s) the stroke finder can put each reversal of motion.reversals from the true one.

    At most 2 e / |a| (e the interpolant's velocity error, a the acceleration there) while
    the acceleration stays above |a| / 2 over that shift and the shift is below the step;
    None where that fails (doc/analysis.md).
    """
    w, h, x = abs(input_speed), sample_interval, motion.ram
    local = _Local(motion, 2.0 * w * h)
    velocity_error = _VELOCITY_CONSTANT * h ** 3 * w ** 4 * local.everywhere(x[4])
    shifts: List[Optional[float]] = []
    for index in motion.reversals.tolist():
        acceleration = w * w * abs(x[2][index]) / MARGIN
        shift = 2.0 * velocity_error[index] / acceleration
        steady = w ** 3 * local.around(x[3], index) * shift <= 0.5 * acceleration
        shifts.append(float(shift) if steady and shift <= h else None)
    return shifts


def position_error_near(motion: SteadyMotion, input_speed: float, sample_interval: float,
                        index: int) -> float:
    """Bound (m) of the interpolant's ram position error within two steps of grid point index."""
    w, h = abs(input_speed), sample_interval
    return (_POSITION_CONSTANT * h ** 4 * w ** 4
            * _Local(motion, 2.0 * w * h).around(motion.ram[4], index))


def _fill(bounds: Dict[str, Optional[float]], theory: SteadyTheory, input_speed: float,
          h: float, motion: SteadyMotion) -> None:
    w = abs(input_speed)
    x = motion.ram
    # Every interval touching a point within one step of it lies within two steps.
    local = _Local(motion, 2.0 * w * h)
    velocity_error = _VELOCITY_CONSTANT * h ** 3 * w ** 4 * local.everywhere(x[4])
    position_error = _POSITION_CONSTANT * h ** 4 * w ** 4 * local.everywhere(x[4])
    shifts = reversal_shifts(motion, input_speed, h)
    if None not in shifts:
        stroke_error = float(sum(shifts))  # type: ignore[arg-type]
        bounds['cutting_time'] = bounds['return_time'] = stroke_error
        bounds['time_ratio'] = _ratio_bound(float(theory.cutting_time),
                                            float(theory.return_time), stroke_error,
                                            stroke_error)
    # The cutting stroke moves toward -x: dx/dt = input_speed dx/dtheta < 0.
    cutting = np.sign(input_speed) * x[1] < 0.0
    speed = w * np.abs(x[1])
    # A stroke's peak is taken over whole intervals, the one holding its first reversal
    # too: the other stroke's last step before it counts (the stroke widened by one step).
    widen = _Local(motion, w * h)
    for name, stroke in (('peak_cutting_speed', cutting), ('peak_return_speed', ~cutting)):
        reach = widen.everywhere(stroke.astype(float)) > 0.0
        peak_error = _extreme_shift(speed, velocity_error, stroke, True, reach)
        bounds[name] = peak_error if peak_error < abs(getattr(theory, name)) else None
    bounds['peak_speed_ratio'] = _ratio_bound(float(theory.peak_return_speed),
                                              float(theory.peak_cutting_speed),
                                              bounds['peak_return_speed'],
                                              bounds['peak_cutting_speed'])
    mid: Dict[bool, Tuple[float, Optional[float]]] = {}
    crossings = np.nonzero((x[0] >= 0.0) != (np.roll(x[0], -1) >= 0.0))[0]
    for index in crossings.tolist():
        crossing_speed = speed[index] / MARGIN
        shift = 2.0 * position_error[index] / crossing_speed
        bend = w * w * local.around(x[2], index)
        error = (velocity_error[index] + bend * shift
                 if bend * shift <= 0.5 * crossing_speed and shift <= h else None)
        mid[bool(cutting[index])] = (crossing_speed, error)
    if len(mid) == 2:
        (returning, return_error), (cut, cut_error) = mid[False], mid[True]
        bounds['speed_ratio'] = _ratio_bound(returning, cut, return_error, cut_error)
    flywheel_speed = w * motion.flywheel_speed
    flywheel_error = _VELOCITY_CONSTANT * h ** 3 * w ** 4 * local.everywhere(
        motion.flywheel_fourth)
    everywhere = np.ones(flywheel_speed.shape, dtype=bool)
    bounds['flywheel_speed_swing'] = _ratio_bound(
        float(np.max(flywheel_speed)), float(np.min(flywheel_speed)),
        _extreme_shift(flywheel_speed, flywheel_error, everywhere, True),
        _extreme_shift(flywheel_speed, flywheel_error, everywhere, False))
