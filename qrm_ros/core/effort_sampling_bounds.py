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

The efforts are measured piece by piece between the load switches (core.piecewise_efforts):
each sample interval takes the cubic through the four nearest samples of its piece. Under
the ideal speed drive the recorded efforts are the theory sampled, and within a piece the
theory is the efforts under that piece's constant load: smooth and periodic over a
revolution, so its derivatives come by FFT (on grids doubled until the fourth derivative
settles, raised by sampling_bounds.MARGIN). A cubic through four points within steps of at
most h errs at t by at most max|f''''| / 24 |prod (t - t_i)|, the product at most 0.5625 h^4
on a centred interval, h^4 on a piece's first or last one and 24 h^4 beyond its last sample
(carried to the piece's end). The figures' bounds follow (doc/analysis.md derives them): an
integral by the error integrated, plus what the switches' placement can move (a workpiece
edge found within 2 e / |v| of the true one, e the interpolated ram position's error; the
pair's ends within the reversals' shifts); a peak as sampling_bounds bounds a peak speed.
Where a piece holds too few samples for its cubic, the drive is the motor's (its steady
running is simulated, not in closed form), or the derivatives do not settle within the
grid, the bound is None: the sampling supports no figure.
"""

import math
from typing import Dict, List, NamedTuple, Optional, Tuple

import numpy as np
from scipy.ndimage import maximum_filter1d

from qrm_ros.core import dynamics as dyn
from qrm_ros.core.effort_theory import EFFORT_FIGURES
from qrm_ros.core.geometry import Geometry, TWO_PI
from qrm_ros.core.mechanism_state import state
from qrm_ros.core.piecewise_efforts import MIN_PIECE_SAMPLES, STENCIL_POINTS
from qrm_ros.core.sampling_bounds import (MARGIN, position_error_near, reversal_shifts,
                                          SteadyMotion)
from qrm_ros.core.speed_drive import load_switch_angles

__all__ = ['EFFORT_BOUNDED_FIGURES', 'effort_sampling_bounds', 'steady_efforts',
           'SteadyEfforts']

# The effort figures given a sampling bound (the flywheel speed swing is a kinematic one).
EFFORT_BOUNDED_FIGURES = EFFORT_FIGURES + ('speed_fluctuation',)
# max |prod (t - t_i)| / h^4 of the cubic's four nodes: a centred interval, a piece's first
# or last interval, the stretch beyond a piece's last sample (at most one step).
_CENTRED, _END_INTERVAL, _BEYOND = 0.5625, 1.0, 24.0
# Lagrange weights' sum beyond the last node (1 + 4 + 6 + 4): what one sample read on the
# wrong side of a reversal (where the efforts only bend) can do to the cubic.
_LEBESGUE = 15.0
_FIRST_GRID, _LAST_GRID = 1024, 1 << 17
_AGREEMENT = 1e-3


def _spectral(values: np.ndarray, order: int) -> np.ndarray:
    spectrum = np.fft.rfft(values)
    return np.fft.irfft(spectrum * (1j * np.arange(spectrum.size)) ** order, n=values.size)


class SteadyEfforts(NamedTuple):
    """One revolution's efforts on a grid of input angle, each load's smooth extension."""

    theta: np.ndarray  # input angle (rad), evenly spaced over [0, 2 pi)
    load: np.ndarray  # the ram load (N) in force at each grid point
    switches: np.ndarray  # input angles (rad, in [0, 2 pi)) of the load switches
    is_edge: np.ndarray  # True for a workpiece edge, False for a reversal
    # Per signal (input torque x input speed, torque^2, torque, offset force): value, first
    # and fourth derivatives in input angle at each grid point, under its own piece's load.
    signals: Dict[str, Tuple[np.ndarray, np.ndarray, np.ndarray]]
    # Per switch, each signal's value on either side (before, after), and |dx/dtheta| there.
    sides: Dict[str, np.ndarray]
    ram_slope: np.ndarray


_SIGNALS = ('power', 'torque_squared', 'torque', 'offset_force')


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
            for slot, derived in enumerate((values, _spectral(values, 1),
                                            _spectral(values, 4))):
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
        if not loads.cutting_length > 0.0:  # no workpiece: the measurement splits no edge
            angles, is_edge = angles[:2], is_edge[:2]
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
        points = _FIRST_GRID
        previous = _on_grid(geometry, mass, offset, input_speed, switches, loads_of_pieces,
                            points)
        while True:
            points *= 2
            if points > _LAST_GRID:
                return None
            current = _on_grid(geometry, mass, offset, input_speed, switches,
                               loads_of_pieces, points)
            if all(abs(np.max(np.abs(current[2][name][2]))
                       - np.max(np.abs(previous[2][name][2])))
                   <= _AGREEMENT * np.max(np.abs(current[2][name][2])) for name in _SIGNALS):
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
    if not all(np.all(np.isfinite(part)) for parts in signals.values() for part in parts):
        return None
    return SteadyEfforts(theta, load, switches, is_edge, signals, sides, slope)


def _distance_to_switch(efforts: SteadyEfforts) -> np.ndarray:
    gaps = np.abs(efforts.theta[:, None] - efforts.switches[None, :])
    return np.min(np.minimum(gaps, TWO_PI - gaps), axis=1)


def effort_sampling_bounds(efforts: Optional[SteadyEfforts], motion: Optional[SteadyMotion],
                           theory: Dict[str, Optional[float]], input_speed: float,
                           sample_interval: float) -> Dict[str, Optional[float]]:
    """
    Bound of each figure of EFFORT_BOUNDED_FIGURES's error from the sampling, in its unit.

    efforts: steady_efforts' answer (None: the motor drive, or unresolved); motion:
    sampling_bounds.steady_motion's for the same setting; theory: the figures' exact values
    (effort_theory); sample_interval (s): the longest step. None where no bound holds.
    """
    bounds: Dict[str, Optional[float]] = dict.fromkeys(EFFORT_BOUNDED_FIGURES)
    if efforts is None or motion is None or any(
            theory.get(name) is None for name in EFFORT_FIGURES) or not (
            math.isfinite(sample_interval) and sample_interval > 0.0):
        return bounds
    bounds['speed_fluctuation'] = 0.0  # a constant recorded speed: measured exactly 0
    with np.errstate(all='ignore'):
        found = _bounds(efforts, motion, theory, input_speed, sample_interval)
    if found is not None:
        bounds.update(found)
    return {name: (None if value is None or not math.isfinite(value) else float(value))
            for name, value in bounds.items()}


def _switch_shifts(efforts, motion, input_speed, h) -> Optional[Tuple[float, List[float]]]:
    """How far (s) the pair's ends and each switch can be found from the true ones."""
    w = abs(input_speed)
    reversal = reversal_shifts(motion, input_speed, h)
    if None in reversal:
        return None
    ends = max(reversal)  # type: ignore[type-var]  # checked: no None
    shifts = []
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


def _bounds(efforts, motion, theory, input_speed, h):
    w = abs(input_speed)
    step = w * h  # rad
    spacing = TWO_PI / efforts.theta.size
    lengths = np.diff(np.concatenate([efforts.switches, efforts.switches[:1] + TWO_PI]))
    if np.min(lengths) < (MIN_PIECE_SAMPLES + 1) * step:
        return None  # a piece may hold fewer samples than its cubic needs
    shifts = _switch_shifts(efforts, motion, input_speed, h)
    if shifts is None:
        return None
    ends, switch_shifts = shifts
    near = _distance_to_switch(efforts)
    factor = np.where(near <= step + spacing, _BEYOND,
                      np.where(near <= 2.0 * step + spacing, _END_INTERVAL, _CENTRED))
    reach = min(efforts.theta.size // 2,
                int(math.ceil(STENCIL_POINTS * step / spacing)) + 1)
    error = {}
    for name, (_, _, fourth) in efforts.signals.items():
        envelope = maximum_filter1d(np.abs(fourth), 2 * reach + 1, mode='wrap') * MARGIN
        error[name] = envelope * step ** 4 * factor / 24.0
    period = TWO_PI / w

    def integral_bound(name):
        values, slope, _ = efforts.signals[name]
        total = float(np.sum(error[name])) * spacing / w
        sides = efforts.sides[name]
        for k, shift in enumerate(switch_shifts):
            jump = abs(sides[k, 1] - sides[k, 0])
            kink = float(np.max(np.abs(slope))) * w * MARGIN
            total += jump * shift + _LEBESGUE * kink * shift * 2.0 * h
        return total + 2.0 * float(np.max(np.abs(sides))) * ends

    def peak_bound(name):
        values, slope, _ = efforts.signals[name]
        sides = np.abs(efforts.sides[name])
        magnitude = np.concatenate([np.abs(values), sides[:, 0], sides[:, 1]])
        beyond = np.max(error[name]) if error[name].size else 0.0
        errors = np.concatenate([error[name], np.full(2 * sides.shape[0], beyond)])
        top = int(np.argmax(magnitude))
        shift = float(np.max(np.abs(slope))) * w * MARGIN * max(switch_shifts) * (
            1.0 + _LEBESGUE)
        return float(max(np.max(magnitude + errors) - magnitude[top], errors[top])) + shift

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
