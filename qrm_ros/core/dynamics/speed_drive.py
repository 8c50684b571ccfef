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
The ideal speed drive: exact per-pair efforts and the peak input torque (pure numpy/scipy).

The input turns at a constant speed with the offset fixed. The ram load is discontinuous
(doc/dynamics.md): at every stroke reversal and at the workpiece's edges during a cut.
Between those switches every effort is a smooth function of time, so each revolution is
split there and every smooth piece is integrated and searched for its peaks on its own;
that is what makes the per-pair figures exact to quadrature accuracy.
"""

import math
import threading
from typing import NamedTuple

import numpy as np

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.numerics.gauss_legendre import gauss_legendre
from qrm_ros.core.kinematics.geometry import check_offset, Geometry, KinematicsError
from qrm_ros.core.kinematics.mechanism_state import (input_angle_for_flywheel_angle,
                                                     reversal_flywheel_angles, state)
from qrm_ros.core.kinematics.peak_speeds import flat_design

__all__ = ['load_switch_angles', 'MAX_EFFORT_PANELS', 'PairEfforts', 'pair_efforts',
           'PEAK_CANDIDATE_MARGIN', 'peak_input_torque', 'ToleranceUnreachable']

# Gauss-Legendre rule of each panel, and when the adaptive quadrature keeps a panel: its
# rule and the rule on its two halves agree to this fraction of the halves' integral of
# |torque| and of torque^2 (the halves' own error is then smaller by orders of magnitude).
_GAUSS_ORDER = 20
_GAUSS_NODES, _GAUSS_WEIGHTS = gauss_legendre(_GAUSS_ORDER)
_PANELS_PER_REVOLUTION = 16
_PANEL_TOLERANCE = 1e-13
# A disagreement below _ROUNDOFF_SUSPECT that halving shrinks by less than _STALLED_RATIO
# is round-off (a resolved panel's disagreement falls by about 2^-40 per halving).
_ROUNDOFF_SUSPECT = 1e-9
_STALLED_RATIO = 0.1
_MAX_PANEL_LEVELS = 40
# Panels the integrals may evaluate in all: 57 at offset 0, 167 at 0.999 coupling_radius;
# nearer the coupling radius the round-off floor keeps panels splitting, and without a bound
# 0.9999 r1 took gigabytes. 20000 is about 30 MB of samples and a second.
MAX_EFFORT_PANELS = 20_000
# Peak refinement: samples across each bracket per round; each round narrows the bracket to
# two sample spacings (1/16), so the rounds take it to about 4e-9 of a sample spacing.
_ZOOM_SAMPLES = 33
_ZOOM_ROUNDS = 7
# Sampled local maxima this far below the largest sample are not refined: between samples
# a smooth piece rises far less than this.
PEAK_CANDIDATE_MARGIN = 0.01


class PairEfforts(NamedTuple):
    """Input-side figures of one stroke pair (N m, N m, W, J, N)."""

    peak_input_torque: float
    rms_input_torque: float
    mean_input_power: float
    energy_per_pair: float
    peak_offset_force: float


def _speed(input_speed):
    """Return the checked input speed (float or array), refusing a zero anywhere."""
    input_speed = dyn.checked_quantity('input_speed', input_speed, 'rad/s')
    if np.any(np.asarray(input_speed) == 0.0):
        raise KinematicsError('input_speed must be non-zero (rad/s): a stopped shaft has no '
                              'stroke pairs')
    return input_speed


def load_switch_angles(geometry: Geometry, loads: dyn.Loads, offset: float) -> np.ndarray:
    """
    Return the input angles (rad) where the ram load can switch: reversals, workpiece edges.

    Both in closed form on the flywheel, then through the coupling's inverse. At an edge
    H tan(psi) = +-L_c / 2 with tan(psi) = r cos(c) / (h + r sin(c)), c the crank angle:
    r cos(c) - t r sin(c) = t h, i.e. cos(c + atan(t)) = t h / (r sqrt(1 + t^2)).
    """
    flywheel = list(reversal_flywheel_angles(geometry))
    r, h = geometry.crank_radius, geometry.pivot_distance
    for side in (1.0, -1.0):
        tangent = side * 0.5 * loads.cutting_length / geometry.ram_height
        cosine = tangent * h / (r * math.hypot(1.0, tangent))
        if abs(cosine) <= 1.0:  # beyond: a workpiece as long as the stroke (edges = reversals)
            spread = math.acos(cosine)
            flywheel += [turn - math.atan(tangent) - geometry.crank_phase
                         for turn in (spread, -spread)]
    return np.asarray(input_angle_for_flywheel_angle(geometry, offset, np.array(flywheel)))


class ToleranceUnreachable(dyn.DynamicsError):
    """The theory cannot be worked out to its tolerance within its bounded cost."""


def _smooth_pieces(geometry, loads, offset, input_speed, period):
    """Split one revolution (s) at the load switches: (starts, ends, load on each, N)."""
    times = np.mod(load_switch_angles(geometry, loads, offset) / input_speed, period)
    bounds = np.unique(np.concatenate([[0.0, period], times[times < period]]))
    starts, ends = bounds[:-1], bounds[1:]
    middle = state(geometry, offset, input_speed * 0.5 * (starts + ends), input_speed)
    load = dyn.ram_load_force(loads, middle.ram_position, middle.ram_velocity,
                              geometry.ram_stroke)
    return starts, ends, np.asarray(load, dtype=float)


class _SpeedDriveEfforts:
    """Input torque and offset force at a constant input speed and offset, the load given."""

    def __init__(self, geometry, mass, offset, input_speed):
        self._fixed = (dyn.ARRAY_OPS, *dyn.geometry_fields(geometry), mass.scalars(),
                       offset)
        self._speed = input_speed

    def __call__(self, times, loads):
        """Return (input torque, offset force) at times (s) under ram loads (N)."""
        result = dyn.evaluate_chain(*self._fixed, self._speed * times, self._speed, 0.0, 0.0,
                                    0.0, loads).efforts
        return result.input_torque, result.offset_force


def _gauss_panels(evaluate, low, high, loads):
    """Apply the Gauss rule on each panel: nodes, torques, forces; integrals of t, t^2, |t|."""
    half = 0.5 * (high - low)[:, None]
    nodes = 0.5 * (low + high)[:, None] + half * _GAUSS_NODES
    torque, force = evaluate(nodes, loads[:, None])
    weights = half * _GAUSS_WEIGHTS
    return (nodes, torque, force, np.sum(weights * torque, axis=1),
            np.sum(weights * torque * torque, axis=1),
            np.sum(weights * np.abs(torque), axis=1))


def _integrate_pieces(evaluate, starts, ends, loads, period):
    """
    Integrate the torque and its square over the pieces; return them and the samples taken.

    Adaptive Gauss-Legendre: panels of at most 1/16 revolution, each halved until its rule
    agrees with its halves' (vectorised over all panels of a level). Near the coupling
    radius the torque itself carries round-off of about eps r1^2 / (r1 - |offset|)^2; a
    panel whose halving no longer shrinks an already small disagreement is at that floor
    and is kept. The samples are the kept panels' nodes: (piece, time, torque, offset
    force), flat.
    """
    counts = [max(1, math.ceil((end - start) * _PANELS_PER_REVOLUTION / period))
              for start, end in zip(starts, ends)]
    edges = [np.linspace(start, end, count + 1) for start, end, count
             in zip(starts, ends, counts)]
    low = np.concatenate([edge[:-1] for edge in edges])
    high = np.concatenate([edge[1:] for edge in edges])
    piece = np.repeat(np.arange(starts.size), counts)
    coarse = _gauss_panels(evaluate, low, high, loads[piece])
    before = np.full(low.size, math.inf)
    integral = square = 0.0
    samples = []
    evaluated = low.size
    for _ in range(_MAX_PANEL_LEVELS):
        evaluated += 2 * low.size
        if evaluated > MAX_EFFORT_PANELS:
            raise ToleranceUnreachable(
                f'the effort integrals cannot be worked out to their tolerance within '
                f'{MAX_EFFORT_PANELS} panels (offset too near the coupling radius: its '
                'round-off grows as (r1 / (r1 - |offset|))^2)')
        middle = 0.5 * (low + high)
        halves_low, halves_high = np.concatenate([low, middle]), np.concatenate([middle, high])
        halves_piece = np.concatenate([piece, piece])
        fine = _gauss_panels(evaluate, halves_low, halves_high, loads[halves_piece])
        count = low.size
        torque, torque2, size = (value[:count] + value[count:] for value in fine[3:])
        with np.errstate(invalid='ignore', divide='ignore'):
            miss = np.maximum(np.abs(torque - coarse[3]) / size,
                              np.abs(torque2 - coarse[4]) / torque2)
        miss[size == 0.0] = 0.0
        done = (miss <= _PANEL_TOLERANCE) | (
            (miss <= _ROUNDOFF_SUSPECT) & (miss >= _STALLED_RATIO * before))
        integral += math.fsum(torque[done])
        square += math.fsum(torque2[done])
        kept = np.concatenate([done, done])
        samples.append((np.repeat(halves_piece[kept], _GAUSS_ORDER),
                        *(value[kept].ravel() for value in fine[:3])))
        if np.all(done):
            break
        low, high, piece = halves_low[~kept], halves_high[~kept], halves_piece[~kept]
        coarse = tuple(value[~kept] for value in fine)
        before = np.tile(miss[~done], 2)
    else:
        raise dyn.DynamicsError('the effort integrals did not converge in '
                                f'{_MAX_PANEL_LEVELS} halvings (offset too near the '
                                'coupling radius?)')
    return integral, square, [np.concatenate(column) for column in zip(*samples)]


def _peaks(evaluate, starts, ends, loads, samples):
    """
    Return max |torque| and max |offset force| over the pieces.

    Every local maximum of the samples (piece ends included, with the piece's own load)
    near the largest is refined by zooming in on it; vectorised over all of them.
    """
    end_torque, end_force = evaluate(np.concatenate([starts, ends]), np.tile(loads, 2))
    piece = np.concatenate([samples[0], np.arange(starts.size), np.arange(starts.size)])
    times = np.concatenate([samples[1], starts, ends])
    order = np.lexsort((times, piece))
    piece, times = piece[order], times[order]
    same_before = np.concatenate([[False], piece[1:] == piece[:-1]])
    same_after = np.concatenate([piece[:-1] == piece[1:], [False]])
    before = np.maximum(np.arange(times.size) - 1, 0)
    after = np.minimum(np.arange(times.size) + 1, times.size - 1)
    best, low, high, load, kind = [], [], [], [], []
    for which, values in enumerate((np.concatenate([samples[2], end_torque]),
                                    np.concatenate([samples[3], end_force]))):
        values = np.abs(values[order])
        top = float(np.max(values))
        best.append(top)
        local = ((~same_before | (values >= values[before]))
                 & (~same_after | (values >= values[after]))
                 & (values >= (1.0 - PEAK_CANDIDATE_MARGIN) * top) & (top > 0.0))
        index = np.nonzero(local)[0]
        low.append(np.where(same_before[index], times[before[index]], times[index]))
        high.append(np.where(same_after[index], times[after[index]], times[index]))
        load.append(loads[piece[index]])
        kind.append(np.full(index.size, which))
    low, high, load, kind = (np.concatenate(column) for column in (low, high, load, kind))
    steps = np.linspace(0.0, 1.0, _ZOOM_SAMPLES)
    rows = np.arange(low.size)
    for _ in range(_ZOOM_ROUNDS):
        times = low[:, None] + (high - low)[:, None] * steps
        torque, force = evaluate(times, load[:, None])
        values = np.abs(np.where(kind[:, None] == 0, torque, force))
        top = np.argmax(values, axis=1)
        for which in (0, 1):
            chosen = kind == which
            if np.any(chosen):
                best[which] = max(best[which], float(np.max(values[rows[chosen], top[chosen]])))
        low = times[rows, np.maximum(top - 1, 0)]
        high = times[rows, np.minimum(top + 1, _ZOOM_SAMPLES - 1)]
    return best


def pair_efforts(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads, offset: float,
                 input_speed: float) -> PairEfforts:
    """
    Return the input-side ``PairEfforts`` of one revolution under an ideal speed drive.

    The input turns at the constant input_speed (rad/s, non-zero) with the offset (m) fixed;
    energy_per_pair is the work the drive does in the revolution (the integral of the input
    torque over the angle turned), mean_input_power that work over the revolution's time,
    rms_input_torque the root mean square over time.

    The revolution is split where the load switches (closed form); each smooth piece is
    integrated by adaptive Gauss-Legendre to round-off and its peaks are refined from dense
    samples, so the figures are exact to round-off: about 1e-13 relative within the safe
    offsets, growing as (r1 / (r1 - |offset|))^2 toward the coupling radius.
    """
    offset = float(check_offset(geometry, offset))
    input_speed = _speed(input_speed)
    loads.check_against(geometry.ram_stroke)
    period = 2.0 * math.pi / abs(input_speed)
    starts, ends, load = _smooth_pieces(geometry, loads, offset, input_speed, period)
    evaluate = _SpeedDriveEfforts(geometry, mass, offset, input_speed)
    integral, square, samples = _integrate_pieces(evaluate, starts, ends, load, period)
    peak_torque, peak_force = _peaks(evaluate, starts, ends, load, samples)
    energy = input_speed * integral
    return PairEfforts(peak_input_torque=peak_torque,
                       rms_input_torque=math.sqrt(square / period),
                       mean_input_power=energy / period, energy_per_pair=energy,
                       peak_offset_force=peak_force)


# peak_input_torque's search (qrm_ros.core.dynamics.torque_kernel): even crank-angle samples on the
# cut and on the return (the return's grow as sqrt(h / (h - r)); besides the load switches and the
# coupling's two crossings). Against 400 and 400 on 3 x 10^5 random designs (r/h to 0.97,
# offsets to 0.99 r1) under three loads each: 12 and 8 lost no peak (8 and 6 one, by 2e-3;
# before intervals hiding a minimum and a maximum were split, 24 and 16 lost some). Brent's
# method stops once the root of d(torque)/d(phi_c) is bracketed within the tolerance
# (rad): the peak value's error is of the order of its square.
_TORQUE_SAMPLES = (12, 8)
_TORQUE_ANGLE_TOLERANCE = 1e-9
_TORQUE_MAX_STEPS = 100
# One caller at a time in the kernel's parallel loop: numba's workqueue threading layer (the
# one left where no OpenMP or TBB library is found) aborts the process on concurrent calls.
_KERNEL_LOCK = threading.Lock()


def peak_input_torque(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                      offset: dyn.FloatOrArray,
                      input_speed: dyn.FloatOrArray) -> dyn.FloatOrArray:
    """
    Return the largest |input torque| (N m) of a revolution under the ideal speed drive.

    pair_efforts' peak_input_torque for many configurations at once: the input turns at the
    constant input_speed (rad/s, non-zero, either sign) with the offset (m) fixed, the ram
    under ``dynamics.ram_load_force``. Geometry fields (arrays allowed), offset and
    input_speed broadcast (as ``kinematics.peak_ram_speeds``); mass and loads are single
    sets. Exact to round-off: each smooth piece of the revolution (split where the load
    switches) is searched for its peaks by the compiled qrm_ros.core.dynamics.torque_kernel, piece
    ends with the piece's own load (at a workpiece edge the torque jumps; its one-sided limits
    count). A float for scalar arguments, an array of the broadcast shape otherwise. Large
    sweeps run on numba's threads (numba.set_num_threads); the first call in a process
    loads the kernel (0.3 s; 5 s once after an install, compiling it). Without numba each
    configuration goes through pair_efforts (1.4 ms each).
    """
    design_shape, flat = flat_design(geometry, offset)
    speed = np.asarray(_speed(input_speed), dtype=float)
    masses, load = mass.scalars(), loads.scalars()
    loads.check_against(float(np.min(geometry.ram_stroke)))
    shape = np.broadcast_shapes(design_shape, speed.shape)
    flat = [np.array(np.broadcast_to(value, shape).reshape(-1))
            for value in (*(value.reshape(design_shape) for value in flat), speed)]
    try:  # imported here: numba is optional and slow to load
        from qrm_ros.core.dynamics import torque_kernel
    except ImportError:  # without numba: pair_efforts for each configuration
        peaks = np.array([
            pair_efforts(Geometry(*values[:5]), mass, loads, values[5], values[6])
            .peak_input_torque for values in zip(*(v.tolist() for v in flat))])
    else:
        with _KERNEL_LOCK:
            r1, r, h, height, phase, offset_values, speeds = flat
            peaks = torque_kernel.peak_torques(
                r1, r, h, height, phase, offset_values, speeds,
                masses['flywheel_inertia'], masses['lever_inertia'], masses['ram_mass'],
                masses['lever_mass'] * masses['gravity'] * masses['lever_com_distance'],
                load['cutting_force'], load['ram_friction'], load['cutting_length'],
                *_TORQUE_SAMPLES, _TORQUE_ANGLE_TOLERANCE, _TORQUE_MAX_STEPS)
    return float(peaks[0]) if shape == () else peaks.reshape(shape)
