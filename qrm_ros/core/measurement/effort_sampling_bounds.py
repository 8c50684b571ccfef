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
How far the sampling alone can move each measured effort figure: a bound, not an estimate.

The efforts are measured piece by piece between the load switches
(core.measurement.piecewise_efforts): each sample interval takes the polynomial through the n
nearest samples of its piece (a quintic for the integrals, a cubic for the peaks). Under the ideal
speed drive the recorded efforts are the theory sampled, and within a piece the theory is the
efforts under that piece's constant load: smooth and periodic over a revolution, so its derivatives
come by FFT (on grids doubled until they settle, raised by sampling_bounds.MARGIN). A polynomial
through n points within steps of at most h errs at t by at most max|f^(n)| / n! times
|prod (t - t_i)|; the product's largest value over an interval, in units of h^n, depends
only on where the interval sits in its piece (centred, near an end, or beyond the last
sample, carried to the piece's end: at most n! h^n), and is worked out once below. The
figures' bounds follow (doc/analysis.md derives them): an integral by the error
integrated, plus what the switches' placement can move (a workpiece edge found within
2 e / |v| of the true one, e the interpolated ram position's error; the pair's ends within
the reversals' shifts); a peak as sampling_bounds bounds a peak speed. Where a piece holds
too few samples, the drive is the motor's (its steady running is simulated, not in closed
form), or the derivatives do not settle within the grid, the bound is None: the sampling
supports no figure.
"""

import math
from typing import Dict, List, NamedTuple, Optional, Tuple

import numpy as np
from scipy.ndimage import maximum_filter1d

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.measurement.effort_theory import EFFORT_FIGURES
from qrm_ros.core.kinematics.geometry import Geometry, TWO_PI
from qrm_ros.core.kinematics.mechanism_state import state
from qrm_ros.core.numerics.portable_math import power
from qrm_ros.core.measurement.piecewise_efforts import (INTEGRAL_POINTS, MIN_PIECE_SAMPLES,
                                                        STENCIL_POINTS)
from qrm_ros.core.measurement.sampling_bounds import (envelope, FIRST_GRID, GRID_AGREEMENT,
                                                      LAST_GRID, MARGIN, position_error_near,
                                                      reversal_shifts, spectral_derivative,
                                                      SteadyMotion, step_on_grid)
from qrm_ros.core.dynamics.speed_drive import load_switch_angles

__all__ = ['EFFORT_BOUNDED_FIGURES', 'effort_sampling_bounds', 'steady_efforts', 'switch_shift',
           'SteadyEfforts']

# The effort figures given a sampling bound (the flywheel speed swing is a kinematic one).
EFFORT_BOUNDED_FIGURES = EFFORT_FIGURES + ('speed_fluctuation',)


def _node_products(points: int) -> np.ndarray:
    """
    Return max |prod (t - t_i)| / h^points over an interval, by where it sits in a piece.

    Element k: for a point at most k + 1 steps from the end (equal steps h; shorter ones
    only shrink the product). Beyond the last sample (k = 0) the polynomial through the
    piece's last points is carried at most one step: points!. The interval holding the
    point is then the m-th of the piece for some m >= k - 1, whose nodes are the piece's
    first points samples, or centred on it once the piece allows; the products shrink
    toward the centre, so each element is the largest over the intervals it may be.
    """
    s = np.linspace(0.0, 1.0, 2001)
    centred = (points - 2) // 2  # the first interval whose stencil is centred
    largest = []
    for m in range(centred + 1):
        start = max(0, m - centred)
        nodes = np.arange(start, start + points) - m
        largest.append(float(np.max(np.abs(np.prod(s[:, None] - nodes[None, :], axis=1)))))
    tail = np.maximum.accumulate(largest[::-1])[::-1]  # the largest over m and beyond
    beyond = float(math.factorial(points))
    return np.concatenate([[max(beyond, tail[0])], tail, tail[-1:]]) * MARGIN


# The products of the peaks' cubic and of the integrals' quintic.
_PEAK_PRODUCTS = _node_products(STENCIL_POINTS)
_INTEGRAL_PRODUCTS = _node_products(INTEGRAL_POINTS)
# The integral of the product beyond a piece's last sample, over at most one step, / h^n+1:
# the two stretches on either side of a switch add up to at most the step that holds it.
_BEYOND_INTEGRAL = MARGIN * float(np.trapezoid(
    np.prod(np.linspace(0.0, 1.0, 2001)[:, None] + np.arange(INTEGRAL_POINTS), axis=1),
    dx=1.0 / 2000))


# Fourier coefficients below this fraction of the largest are round-off: dropped before
# differentiating (the k^n of an nth derivative would raise them above the signal).
_ROUNDOFF = 1e-13


class SteadyEfforts(NamedTuple):
    """One revolution's efforts on a grid of input angle, each load's smooth extension."""

    theta: np.ndarray  # input angle (rad), evenly spaced over [0, 2 pi)
    load: np.ndarray  # the ram load (N) in force at each grid point
    switches: np.ndarray  # input angles (rad, in [0, 2 pi)) of the load switches
    is_edge: np.ndarray  # True for a workpiece edge, False for a reversal
    # Per signal (input torque x input speed, torque^2, torque, offset force): value, first
    # derivative and the derivative its polynomial's error takes (sixth for the integrands,
    # fourth for the peaks) in input angle at each grid point, under its own piece's load.
    signals: Dict[str, Tuple[np.ndarray, np.ndarray, np.ndarray]]
    # Per switch, each signal's value on either side (before, after), and |dx/dtheta| there.
    sides: Dict[str, np.ndarray]
    ram_slope: np.ndarray
    cutting_start: float  # input angle (rad) of the reversal where a stroke pair begins


_SIGNALS = ('power', 'torque_squared', 'torque', 'offset_force')
# The integrands take the quintic, the peaks' signals the cubic: the derivative each needs.
_ORDER = {'power': INTEGRAL_POINTS, 'torque_squared': INTEGRAL_POINTS,
          'torque': STENCIL_POINTS, 'offset_force': STENCIL_POINTS}


def _on_grid(geometry, mass, offset, input_speed, switches, loads_of_pieces, points):
    theta = np.arange(points) * (TWO_PI / points)
    piece = np.searchsorted(switches, theta, side='right') % switches.size
    load = loads_of_pieces[piece]
    signals = {name: [np.empty(points) for _ in range(3)] for name in _SIGNALS}
    for value in np.unique(loads_of_pieces):
        result = dyn.efforts(geometry, mass, offset, theta, input_speed,
                             external_ram_force=float(value))
        torque = np.asarray(result.input_torque)
        series = {'power': input_speed * torque, 'torque_squared': torque * torque,
                  'torque': torque, 'offset_force': np.asarray(result.offset_force)}
        here = load == value
        for name, values in series.items():
            for slot, derived in enumerate((
                    values, spectral_derivative(values, 1, _ROUNDOFF),
                    spectral_derivative(values, _ORDER[name], _ROUNDOFF))):
                signals[name][slot][here] = derived[here]
    return theta, load, {name: tuple(parts) for name, parts in signals.items()}


def steady_efforts(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                   offset: float, input_speed: float) -> Optional['SteadyEfforts']:
    """
    Work out the ideal speed drive's efforts over one revolution; None if unresolved.

    Bounded cost: grids of up to 131072 points whatever the values; where the fourth
    derivatives do not settle on them (an offset a hair below the coupling radius), None.
    """
    if not (math.isfinite(offset) and abs(offset) < geometry.coupling_radius
            and math.isfinite(input_speed) and input_speed != 0.0):
        return None
    with np.errstate(all='ignore'):
        angles = np.asarray(load_switch_angles(geometry, loads, offset), dtype=float)
        is_edge = np.arange(angles.size) >= 2
        # The measurement splits at the edges the tool meets while cutting (the ram moving
        # toward -x), and at none without a workpiece; the return passes them unloaded.
        cutting = np.asarray(state(geometry, offset, angles, input_speed).ram_velocity) < 0.0
        kept = ~is_edge | (cutting & (loads.cutting_length > 0.0))
        angles, is_edge = angles[kept], is_edge[kept]
        angles = np.mod(angles, TWO_PI)
        order = np.argsort(angles)
        switches, is_edge = angles[order], is_edge[order]
        middle = np.mod(0.5 * (switches + np.roll(switches, -1)
                               + np.where(np.arange(switches.size) == switches.size - 1,
                                          TWO_PI, 0.0)), TWO_PI)
        moving = state(geometry, offset, middle, input_speed)
        # The piece after switch k (up to switch k + 1) carries this load.
        after = np.asarray(dyn.ram_load_force(loads, moving.ram_position, moving.ram_velocity,
                                              geometry.ram_stroke), dtype=float)
        loads_of_pieces = np.roll(after, 1)  # grid piece index j: after switch j - 1
        points = FIRST_GRID
        previous = _on_grid(geometry, mass, offset, input_speed, switches, loads_of_pieces,
                            points)
        while True:
            points *= 2
            if points > LAST_GRID:
                return None
            current = _on_grid(geometry, mass, offset, input_speed, switches,
                               loads_of_pieces, points)
            if all(abs(np.max(np.abs(current[2][name][2]))
                       - np.max(np.abs(previous[2][name][2])))
                   <= GRID_AGREEMENT * np.max(np.abs(current[2][name][2])) for name in _SIGNALS):
                break
            previous = current
        theta, load, signals = current
        sides: Dict[str, np.ndarray] = {}
        for name in _SIGNALS:
            sides[name] = np.empty((switches.size, 2))
        for column, piece_loads in enumerate((np.roll(after, 1), after)):
            result = dyn.efforts(geometry, mass, offset, switches, input_speed,
                                 external_ram_force=piece_loads)
            torque = np.asarray(result.input_torque)
            for name, values in (('power', input_speed * torque),
                                 ('torque_squared', torque * torque), ('torque', torque),
                                 ('offset_force', np.asarray(result.offset_force))):
                sides[name][:, column] = values
        slope = np.abs(np.asarray(state(geometry, offset, switches, input_speed).ram_velocity)
                       / input_speed)
        reversals = switches[~is_edge]
        after_turn = state(geometry, offset, reversals + math.copysign(1e-6, input_speed),
                           input_speed)
        begins = reversals[np.asarray(after_turn.ram_velocity) < 0.0]
    if begins.size != 1 or not all(np.all(np.isfinite(part)) for parts in signals.values()
                                   for part in parts):
        return None
    return SteadyEfforts(theta, load, switches, is_edge, signals, sides, slope,
                         float(begins[0]))


def _distance_to_switch(efforts: SteadyEfforts) -> np.ndarray:
    gaps = np.abs(efforts.theta[:, None] - efforts.switches[None, :])
    return np.min(np.minimum(gaps, TWO_PI - gaps), axis=1)


def effort_sampling_bounds(efforts: Optional[SteadyEfforts], motion: Optional[SteadyMotion],
                           theory: Dict[str, Optional[float]], input_speed: float,
                           sample_interval: float,
                           interval_steps: Optional[Tuple[np.ndarray, np.ndarray]] = None
                           ) -> Dict[str, Optional[float]]:
    """
    Bound of each figure of EFFORT_BOUNDED_FIGURES's error from the sampling, in its unit.

    efforts: steady_efforts' answer (None: the motor drive, or unresolved); motion:
    sampling_bounds.steady_motion's for the same setting; theory: the figures' exact values
    (effort_theory); sample_interval (s): the longest step. interval_steps, for one pair
    whose steps differ (a late or lost sample): each sample interval's start (s after the
    pair's first reversal) and length (s), so that each stretch of the revolution is
    bounded at the steps near it, not at the pair's longest. None where no bound holds.
    """
    bounds: Dict[str, Optional[float]] = dict.fromkeys(EFFORT_BOUNDED_FIGURES)
    if efforts is None or motion is None or any(
            theory.get(name) is None for name in EFFORT_FIGURES) or not (
            math.isfinite(sample_interval) and sample_interval > 0.0):
        return bounds
    bounds['speed_fluctuation'] = 0.0  # a constant recorded speed: measured exactly 0
    with np.errstate(all='ignore'):
        found = _bounds(efforts, motion, theory, input_speed, sample_interval,
                        interval_steps)
    if found is not None:
        bounds.update(found)
    return {name: (None if value is None or not math.isfinite(value) else float(value))
            for name, value in bounds.items()}


def switch_shift(efforts: Optional[SteadyEfforts], motion: Optional[SteadyMotion],
                 input_speed: float, sample_interval: float) -> Optional[float]:
    """
    How far (s) a load switch can be found from the true one; None where unbounded.

    A sample nearer than this to a found switch (a reversal or a workpiece edge) may lie
    on its other side, in the other piece: the pair's effort bounds do not hold then (the
    analysis checks it).
    """
    if efforts is None or motion is None:
        return None
    with np.errstate(all='ignore'):
        shifts = _switch_shifts(efforts, motion, input_speed, sample_interval)
    if shifts is None:
        return None
    return float(max(shifts[1], default=0.0))


def _switch_shifts(efforts, motion, input_speed, h) -> Optional[Tuple[float, List[float]]]:
    """How far (s) the pair's ends and each switch can be found from the true ones."""
    w = abs(input_speed)
    reversal = reversal_shifts(motion, input_speed, h)
    if None in reversal:
        return None
    ends = float(max(value for value in reversal if value is not None))
    shifts: List[float] = []
    points = motion.theta.size
    for angle, edge, slope in zip(efforts.switches, efforts.is_edge, efforts.ram_slope):
        if not edge:
            shifts.append(ends)
            continue
        index = int(round(angle / (TWO_PI / points))) % points
        speed = w * slope / MARGIN
        shift = 2.0 * position_error_near(motion, input_speed, h, index) / speed
        bend = w * w * float(np.max(np.abs(motion.ram[2]))) * MARGIN
        if not (speed > 0.0 and shift <= h and bend * shift <= 0.5 * speed):
            return None
        shifts.append(shift)
    return ends, shifts


def _local_steps(efforts, input_speed, h, interval_steps):
    """Return the longest step (rad) among the stencils reaching each grid point."""
    w = abs(input_speed)
    if interval_steps is None:
        return np.full(efforts.theta.size, w * h)
    starts, steps = (np.asarray(part, dtype=float) for part in interval_steps)
    # An interval's polynomial reaches up to INTEGRAL_POINTS samples either way.
    widest = maximum_filter1d(steps, 2 * INTEGRAL_POINTS + 1, mode='nearest')
    period = TWO_PI / w
    since = np.mod((efforts.theta - efforts.cutting_start) / input_speed, period)
    index = np.clip(np.searchsorted(starts, since, side='right') - 1, 0, steps.size - 1)
    # Rounded up to the steps' grid: a few distinct reaches for the envelopes.
    return w * step_on_grid(widest[index])


def _bounds(efforts, motion, theory, input_speed, h, interval_steps=None):
    w = abs(input_speed)
    step = _local_steps(efforts, input_speed, h, interval_steps)  # rad, per grid point
    longest = float(np.max(step))
    spacing = TWO_PI / efforts.theta.size
    lengths = np.diff(np.concatenate([efforts.switches, efforts.switches[:1] + TWO_PI]))
    if np.min(lengths) < (MIN_PIECE_SAMPLES + 1) * longest:
        return None  # a piece may hold fewer samples than its polynomial needs
    shifts = _switch_shifts(efforts, motion, input_speed, longest / w)
    if shifts is None:
        return None
    ends, switch_shifts = shifts
    # How many steps each grid point lies from the nearest switch (the grid's spacing
    # taken off: a point between grid points is no farther).
    distance = np.maximum(_distance_to_switch(efforts) - spacing, 0.0) / step
    gaps = np.abs(efforts.theta[:, None] - efforts.switches[None, :])
    gaps = np.minimum(gaps, TWO_PI - gaps)
    error, placement, beyond = {}, {}, {}
    for name, (_, slope, derivative) in efforts.signals.items():
        points = _ORDER[name]
        products = _PEAK_PRODUCTS if points == STENCIL_POINTS else _INTEGRAL_PRODUCTS
        zone = np.clip(np.ceil(distance).astype(int) - 1, 0, products.size - 1)
        # The polynomial's nodes lie within points steps of any point it is used at (the
        # steps near that point: a late sample widens only its neighbours' reach).
        highest = np.empty(derivative.size)
        for reach in np.unique(step):
            here = step == reach
            highest[here] = envelope(derivative, points * reach, spacing)[here]
        if points == INTEGRAL_POINTS:  # the stretches beyond the samples: integrated below
            products = np.concatenate([[products[1]], products[1:]])
        error[name] = (highest * power(step, points) * products[zone]
                       / math.factorial(points))
        scaled = highest * power(step, points + 1)
        beyond[name] = sum(
            _BEYOND_INTEGRAL * float(np.max(scaled[gaps[:, k] <= step + spacing], initial=0.0))
            for k in range(efforts.switches.size)) / math.factorial(points) / w
        # A switch found off its place (every sample on its own side: switch_shift): the
        # polynomial carried to it moves by at most the slope times the shift.
        placement[name] = np.zeros(efforts.theta.size)
        zones = gaps <= points * longest + spacing
        for k, shift in enumerate(switch_shifts):
            near_switch = zones[:, k]
            steepest = float(np.max(np.abs(slope[near_switch]), initial=0.0)) * w * MARGIN
            placement[name][near_switch] += steepest * shift
        error[name] = error[name] + placement[name]
    period = TWO_PI / w

    def integral_bound(name):
        total = float(np.sum(error[name])) * spacing / w + beyond[name]
        sides = efforts.sides[name]
        for k, shift in enumerate(switch_shifts):
            total += abs(sides[k, 1] - sides[k, 0]) * shift  # the jump, misplaced
        return total + 2.0 * float(np.max(np.abs(sides))) * ends

    def peak_bound(name):
        values = efforts.signals[name][0]
        sides = np.abs(efforts.sides[name])
        magnitude = np.concatenate([np.abs(values), sides[:, 0], sides[:, 1]])
        zones = gaps <= STENCIL_POINTS * longest + spacing
        at_switch = [float(np.max(error[name][zones[:, k]], initial=0.0))
                     for k in range(sides.shape[0])]
        errors = np.concatenate([error[name], at_switch, at_switch])
        top = int(np.argmax(magnitude))
        return float(max(np.max(magnitude + errors) - magnitude[top], errors[top]))

    energy, rms = abs(theory['energy_per_pair']), theory['rms_input_torque']
    energy_error = integral_bound('power')
    square_error = integral_bound('torque_squared')
    duration_error = 2.0 * ends
    if not duration_error < period:
        return None
    squares = rms * rms * period
    return {
        'energy_per_pair': energy_error,
        'mean_input_power': ((energy + energy_error) / (period - duration_error)
                             - energy / period),
        'rms_input_torque': (math.sqrt((squares + square_error) / (period - duration_error))
                             - rms),
        'peak_input_torque': peak_bound('torque'),
        'peak_offset_force': peak_bound('offset_force'),
    }
