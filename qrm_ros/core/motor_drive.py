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
Drive-side answers of the dynamics (pure numpy/scipy, no ROS).

The ram load is discontinuous (dynamics.md): at every stroke reversal and at the workpiece's
edges during a cut. Between those switches every effort is a smooth function of time, so
each revolution is split there and every smooth piece is integrated and searched for its
peaks on its own; that is what makes the per-pair figures exact to quadrature accuracy.
"""

import bisect
import collections
import dataclasses
import gc
import math
import threading
from typing import NamedTuple

import numpy as np
from scipy import integrate, optimize, special

from qrm_ros.core import dynamics as dyn
from qrm_ros.core.checks import finite as _finite, positive as _positive
from qrm_ros.core.geometry import check_offset, Geometry, KinematicsError, TWO_PI
from qrm_ros.core.mechanism_state import (input_angle_for_flywheel_angle,
                                          reversal_flywheel_angles, state)
from qrm_ros.core.peak_speeds import flat_design as _flat_design
from qrm_ros.core.stepping import checked_limits, ramp as _ramp, wrap_angle
from qrm_ros.core.units import NANOSECONDS_PER_SECOND

__all__ = ['MotorStepper', 'PairEfforts', 'Simulation', 'SpeedFluctuation',
           'energy_method_inertia', 'input_inertia_for_speed_fluctuation', 'pair_efforts',
           'peak_input_torque', 'simulate', 'speed_fluctuation']

# Gauss-Legendre rule of each panel, and when the adaptive quadrature keeps a panel: its
# rule and the rule on its two halves agree to this fraction of the halves' integral of
# |torque| and of torque^2 (the halves' own error is then smaller by orders of magnitude).
_GAUSS_ORDER = 20
_GAUSS_NODES, _GAUSS_WEIGHTS = special.roots_legendre(_GAUSS_ORDER)
_PANELS_PER_REVOLUTION = 16
_PANEL_TOLERANCE = 1e-13
# A disagreement below _ROUNDOFF_SUSPECT that halving shrinks by less than _STALLED_RATIO
# is round-off (a resolved panel's disagreement falls by about 2^-40 per halving).
_ROUNDOFF_SUSPECT = 1e-9
_STALLED_RATIO = 0.1
_MAX_PANEL_LEVELS = 40
# Peak refinement: samples across each bracket per round; each round narrows the bracket to
# two sample spacings (1/16), so the rounds take it to about 4e-9 of a sample spacing.
_ZOOM_SAMPLES = 33
_ZOOM_ROUNDS = 7
# Sampled local maxima this far below the largest sample are not refined: between samples
# a smooth piece rises far less than this.
_PEAK_CANDIDATE_MARGIN = 0.01


class PairEfforts(NamedTuple):
    """Input-side figures of one stroke pair (N m, N m, W, J, N)."""

    peak_input_torque: float
    rms_input_torque: float
    mean_input_power: float
    energy_per_pair: float
    peak_offset_force: float


def _speed(input_speed):
    """Return the checked input speed (float or array), refusing a zero anywhere."""
    input_speed = dyn._checked('input_speed', input_speed, 'rad/s')
    if np.any(np.asarray(input_speed) == 0.0):
        raise KinematicsError('input_speed must be non-zero (rad/s): a stopped shaft has no '
                              'stroke pairs')
    return input_speed


def _load_switch_angles(geometry, loads, offset):
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
    return input_angle_for_flywheel_angle(geometry, offset, np.array(flywheel))


def _smooth_pieces(geometry, loads, offset, input_speed, period):
    """Split one revolution (s) at the load switches: (starts, ends, load on each, N)."""
    times = np.mod(_load_switch_angles(geometry, loads, offset) / input_speed, period)
    bounds = np.unique(np.concatenate([[0.0, period], times[times < period]]))
    starts, ends = bounds[:-1], bounds[1:]
    middle = state(geometry, offset, input_speed * 0.5 * (starts + ends), input_speed)
    load = dyn.ram_load_force(loads, middle.ram_position, middle.ram_velocity,
                              geometry.ram_stroke)
    return starts, ends, np.asarray(load, dtype=float)


class _SpeedDriveEfforts:
    """Input torque and offset force at a constant input speed and offset, the load given."""

    def __init__(self, geometry, mass, offset, input_speed):
        self._fixed = (dyn._ARRAY_OPS, *dyn._geometry_fields(geometry), mass.scalars(),
                       offset)
        self._speed = input_speed

    def __call__(self, times, loads):
        """Return (input torque, offset force) at times (s) under ram loads (N)."""
        result = dyn._chain(*self._fixed, self._speed * times, self._speed, 0.0, 0.0, 0.0,
                            loads).efforts
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
    for _ in range(_MAX_PANEL_LEVELS):
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
                 & (values >= (1.0 - _PEAK_CANDIDATE_MARGIN) * top) & (top > 0.0))
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


def pair_efforts(geometry, mass, loads, offset, input_speed):
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


# peak_input_torque's search (qrm_ros.core.torque_kernel): even crank-angle samples on the cut and
# on the return (the return's grow as sqrt(h / (h - r)); besides the load switches and the
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


def peak_input_torque(geometry, mass, loads, offset, input_speed):
    """
    Return the largest |input torque| (N m) of a revolution under the ideal speed drive.

    pair_efforts' peak_input_torque for many configurations at once: the input turns at the
    constant input_speed (rad/s, non-zero, either sign) with the offset (m) fixed, the ram
    under ``dynamics.ram_load_force``. Geometry fields (arrays allowed), offset and
    input_speed broadcast (as ``kinematics.peak_ram_speeds``); mass and loads are single
    sets. Exact to round-off: each smooth piece of the revolution (split where the load
    switches) is searched for its peaks by the compiled qrm_ros.core.torque_kernel, piece ends
    with the piece's own load (at a workpiece edge the torque jumps; its one-sided limits
    count). A float for scalar arguments, an array of the broadcast shape otherwise. Large
    sweeps run on numba's threads (numba.set_num_threads); the first call in a process
    loads the kernel (0.3 s; 5 s once after an install, compiling it). Without numba each
    configuration goes through pair_efforts (1.4 ms each).
    """
    design_shape, flat = _flat_design(geometry, offset)
    speed = np.asarray(_speed(input_speed), dtype=float)
    masses, load = mass.scalars(), loads.scalars()
    loads.check_against(float(np.min(geometry.ram_stroke)))
    shape = np.broadcast_shapes(design_shape, speed.shape)
    flat = [np.array(np.broadcast_to(value, shape).reshape(-1))
            for value in (*(value.reshape(design_shape) for value in flat), speed)]
    try:
        from qrm_ros.core import torque_kernel
    except ImportError:  # without numba: pair_efforts for each configuration
        peaks = np.array([
            pair_efforts(Geometry(*values[:5]), mass, loads, values[5], values[6])
            .peak_input_torque for values in zip(*(v.tolist() for v in flat))])
    else:
        with _KERNEL_LOCK:
            peaks = torque_kernel.peak_torques(
                *flat, masses['flywheel_inertia'], masses['lever_inertia'], masses['ram_mass'],
                masses['lever_mass'] * masses['gravity'] * masses['lever_com_distance'],
                load['cutting_force'], load['ram_friction'], load['cutting_length'],
                *_TORQUE_SAMPLES, _TORQUE_ANGLE_TOLERANCE, _TORQUE_MAX_STEPS)
    return float(peaks[0]) if shape == () else peaks.reshape(shape)


# The integrator's tolerances (DOP853, 8th order): the state is (rad, rad/s).
_RTOL = 1e-12
_ATOL = 1e-12
# Dense-output samples per step when looking for a switch inside it (a function that goes
# out and back within one fifth of a step would be missed; steps are far shorter than the
# load pieces).
_ROOT_SAMPLES = 5
# A step whose sampled angles all stay this far (rad) from the ram's reversals and the
# workpiece's edges (closed form, offset held) has no sign change of those two switching
# functions at its samples, so they are not evaluated there: their computed signs are
# exact beyond about 1e-8 rad (sqrt(eps): a workpiece as long as the stroke touches zero
# at a reversal).
_SWITCH_ANGLE_MARGIN = 1e-6
# A ram reversal landed on with the input slower than this (rad/s) is the shaft stopping.
_STOP_SPEED = 1e-9
# Solver steps taken at once, ahead of the stamps (within the segment: a switch ends them; a
# command or a reset drops what is ahead): the same steps, so the same numbers, run back to
# back about every 10 ticks at 1 kHz. In a running node each step then costs less than alone
# between two ticks (warm caches): the motor node's CPU fell from 1.36-1.51 to 1.21-1.34
# times the speed drive's in two interleaved runs against one step at a time. Sixteen cut it
# further, but their bursts made 1.8 % of the 1 kHz ticks missed (four or six: as the speed
# drive, about 0.2-0.4 %).
_STEPS_AHEAD = 4
# Why a segment of the integration ended (what changed at the restart).
_DIRECTION, _WORK, _SATURATION, _SPIN = range(4)


def _sign(value):
    return int(value > 0.0) - int(value < 0.0)


def _float_dense(dense):
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


class _Dop853(integrate.DOP853):
    """
    scipy's DOP853 at the stepper's tolerances, calling the right-hand side directly.

    OdeSolver wraps the right-hand side (a call counting nfev, then np.asarray of its
    result); the solver stores each result into its stage array, or keeps the last as f and
    adds it to an array (dense output), both of which take the [speed, acceleration] list as
    the array it made of it, so dropping the wrappers changes no number (nfev goes
    uncounted). Construction still goes through them.
    """

    def __init__(self, rhs, time, state, bound):
        super().__init__(rhs, time, state, bound, rtol=_RTOL, atol=_ATOL)
        self.fun = rhs


# The lean acceleration and efforts compiled (qrm_ros.core.motor_kernel, numba): [the module] once
# loaded, [None] while loading or without numba. Importing numba and loading the machine code
# take 0.3-1 s, so the first MotorStepper of a process starts it on a thread of its own; each
# segment, and the efforts at each stamp, take whichever form is there (the two give the
# same numbers bit for bit). That thread interleaves with the ticks (the node's 0.1 ms GIL
# switch interval) but for its C calls that keep the GIL: 3-7 ms each, a few, once per
# process.
_COMPILED_KERNEL = [None]
_COMPILED_LOADED = threading.Event()
_LOADER_LOCK = threading.Lock()
_loader = []


def _load_compiled_kernel():
    # The garbage collector stays off meanwhile: a full collection among numba's new objects
    # took 60 ms with the GIL held (a stall of every other thread); they stay for the
    # process's life, so they are frozen out of later collections (as the nodes freeze
    # theirs before they spin).
    collecting = gc.isenabled()
    gc.disable()
    try:
        from qrm_ros.core import motor_kernel
    except ImportError:  # without numba: the Python form throughout
        pass
    else:
        _COMPILED_KERNEL[0] = motor_kernel
    finally:
        gc.freeze()
        if collecting:
            gc.enable()
        _COMPILED_LOADED.set()


def _start_loading_compiled_kernel():
    with _LOADER_LOCK:
        if not _loader:
            _loader.append(threading.Thread(target=_load_compiled_kernel, daemon=True,
                                            name='qrm_motor_kernel_loader'))
            _loader[0].start()


class MotorStepper:
    """
    The mechanism under a motor drive: the input speed is a state of the equation of motion.

    Same interface and stamp rules as ``stepping.ShaperStepper`` (integer-ns stamps, commands
    from the present stamp, time resets, wrapped angle). The speed command ramps at
    input_acceleration_limit into the motor's speed reference; the offset moves toward its
    command at offset_rate_limit as ShaperStepper moves it. A jump in the offset rate (a ramp
    starting or ending) is an impulse on the offset only, so the input's generalised momentum
    is kept across it and the input speed jumps.

    Integration: scipy's DOP853, restarted at every switch of the right-hand side: stroke
    reversal, tool entering or leaving the workpiece, motor reaching or leaving its torque
    limit, input speed through zero, a ramp ending, any command. A switch inside a step is
    found on the step's dense output with brentq, and the step is cut there; a step whose
    samples keep clear of the load's switch angles (closed form) and of the motor's limit
    skips the switching functions (the same switches, found cheaper). Outputs at stamps
    come from dense output, so the trajectory does not depend on the stamps asked for; the
    steps are taken a few at a time ahead of the stamps, within a segment.

    Stall rule: when the input speed reaches zero, the load seen by each direction of motion
    is the one that motion would meet (friction against it; the cutting force if the ram
    would move toward -x inside the workpiece). The shaft moves forward if the motor's
    torque at zero speed beats the forward load's torque, backward likewise, else it is held
    at rest (angle and offset still). Held with a non-zero speed reference is a stall:
    ``stalled`` is True and ``stall_reason`` says why. The rule is re-checked at every step
    (loads, motor and commands may change), and the shaft resumes as soon as it allows.

    motor=None runs the shaft free (no motor torque).
    """

    def __init__(self, geometry, mass, loads, motor, input_speed, offset,
                 input_acceleration_limit, offset_rate_limit):
        self._geometry = geometry
        self._acceleration_limit = _positive('input_acceleration_limit',
                                             input_acceleration_limit, 'rad/s^2')
        self._offset_rate_limit = _positive('offset_rate_limit', offset_rate_limit, 'm/s')
        self._set_dynamics(mass, loads, motor)
        _start_loading_compiled_kernel()
        self.time_resets = 0
        # Called with (start, end, dense output) of every piece of trajectory as it is made,
        # while its segment is still in force (speed_fluctuation's exact extremes).
        self._observer = None
        self.reset(input_speed, offset)

    # Commands -----------------------------------------------------------------------------

    def _set_dynamics(self, mass, loads, motor):
        self._mass = mass
        # The chain's fixed arguments: math's functions, the geometry, the masses as floats.
        self._fixed = (dyn._SCALAR_OPS, *dyn._geometry_fields(self._geometry), mass.scalars())
        self._lean_constants = dyn._lean_constants(self._geometry, mass)
        self._lean_array = np.array(self._lean_constants)  # the compiled forms take an array
        self._ram_motion = dyn._lean_ram_motion(self._lean_constants)
        self._switch_angles_at = (None, None, None)
        self._loads = loads.check_against(self._geometry.ram_stroke)
        loads.scalars()
        self._motor = motor
        if motor is not None:
            motor.scalars()

    def _changed(self, change):
        """Apply change at the present stamp: the state there starts a new segment."""
        self._acceleration_now = None
        if self._stamp_ns is None:
            change()
            if self._spin:  # a held state (resync) reads the new settings as before
                (_, self._acceleration_at, self._switching, self._clear,
                 self._motor_holds) = self._segment_functions()
            return
        angle, speed = self._angle, self._speed
        reference, offset = self._reference_at(self._time), self._offset_at(self._time)
        change()
        self._start(self._time, angle, speed, reference, offset, None)

    def set_dynamics(self, mass=None, loads=None, motor=None):
        """Change masses, loads or motor (None keeps each) from the present stamp."""
        mass = self._mass if mass is None else mass
        loads = self._loads if loads is None else loads
        motor = self._motor if motor is None else motor
        self._changed(lambda: self._set_dynamics(mass, loads, motor))

    def set_speed_command(self, input_speed):
        """Command the input speed (rad/s): the motor's reference ramps to it."""
        command = _finite('input_speed', input_speed, 'rad/s')
        self._changed(lambda: setattr(self, '_speed_command', command))

    def set_offset_command(self, offset):
        """Command the coupling offset (m, |offset| < coupling_radius); moved at the limit."""
        command = float(check_offset(self._geometry, offset))
        self._changed(lambda: setattr(self, '_offset_command', command))

    def set_limits(self, input_acceleration_limit=None, offset_rate_limit=None):
        """Change either limit (rad/s^2, m/s; > 0); None keeps the present value."""
        acceleration, rate = checked_limits(self._acceleration_limit, self._offset_rate_limit,
                                            input_acceleration_limit, offset_rate_limit)

        def change():
            self._acceleration_limit, self._offset_rate_limit = acceleration, rate
        self._changed(change)

    def reset(self, input_speed, offset):
        """Input angle to zero; speed, reference and offset set at once; new time base next."""
        input_speed = _finite('input_speed', input_speed, 'rad/s')
        offset = float(check_offset(self._geometry, offset))
        self._speed_command = input_speed
        self._offset_command = offset
        self._angle, self._speed = 0.0, input_speed
        self._segment_reference, self._segment_offset = input_speed, offset
        self._segment_start = 0.0
        self._reference_end = self._offset_end = -math.inf
        self._offset_rate = 0.0
        self._stamp_ns = None
        self._time = 0.0
        self._solver = None
        self._spin = 0
        self._stall_reason = None
        self._load = 0.0
        self._saturation = 0
        self._piece = (0.0, 0.0, None)
        # Pieces of the segment made ahead of the stamps, in order: (start, end, float dense).
        self._ahead = collections.deque()
        # A switch found in the last step, its segment not started yet: (time, angle, speed,
        # kind) once the stamps pass it.
        self._pending = None
        self._acceleration_now = None

    def restore(self, stamp_ns, input_angle, input_speed, offset, speed_reference=None):
        """
        Take a recorded state as the present one, at its stamp (to replay a logged run).

        The motor's speed reference (rad/s) is part of the state here; it and the speed
        command default to input_speed, as ShaperStepper's commands equal its state.
        """
        input_angle = _finite('input_angle', input_angle, 'rad')
        reference = input_speed if speed_reference is None else speed_reference
        reference = _finite('speed_reference', reference, 'rad/s')
        self.reset(input_speed, offset)
        self._segment_reference = self._speed_command = reference
        self._angle = wrap_angle(input_angle)
        self._new_base(int(stamp_ns))

    def resync(self):
        """Hold the state: the next step starts a new time base (used after a pause)."""
        self._stamp_ns = None

    # Segments -----------------------------------------------------------------------------

    def _new_base(self, stamp_ns):
        self._stamp_ns = self._base_ns = stamp_ns
        self._time = 0.0
        self._piece = (0.0, 0.0, None)
        self._start(0.0, self._angle, self._speed, self._reference_at(None),
                    self._offset_at(None), None)

    def _reference_at(self, time):
        """Return the motor's speed reference (rad/s) at time (s; None: the segment's start)."""
        if time is None:
            return self._segment_reference
        if time >= self._reference_end:
            return self._speed_command
        return _ramp(self._segment_reference, self._speed_command, self._acceleration_limit,
                     time - self._segment_start)[0]

    def _offset_at(self, time):
        if time is None or self._spin == 0:
            return self._segment_offset  # held at rest
        if time >= self._offset_end:
            return self._offset_command
        return _ramp(self._segment_offset, self._offset_command, self._offset_rate_limit,
                     time - self._segment_start)[0]

    def _chain(self, offset, angle, speed, offset_rate):
        """Evaluate the chain at zero input acceleration; all arguments plain floats."""
        return dyn._chain(*self._fixed, offset, angle, speed, 0.0, offset_rate, 0.0, 0.0)

    def _motor_torque(self, reference, speed, saturation):
        if self._motor is None:
            return 0.0
        if saturation:
            return saturation * self._motor.max_torque
        return self._motor.speed_stiffness * (reference - speed)

    def _loaded(self, direction, in_work):
        loads = self._loads
        cutting = loads.cutting_force if direction < 0 and in_work else 0.0
        return cutting - loads.ram_friction * direction

    def _acceleration(self, chain, torque, load):
        bias = chain.efforts.input_torque - load * chain.ram_lever_arm
        return (torque - bias) / chain.generalized_inertia

    def _segment_functions(self):
        """
        Return the present segment's right-hand side, acceleration and switching functions.

        acceleration(time, angle, speed) is the input's (rad/s^2) from the equation of
        motion; switching(time, angle, speed) the values that stay > 0 while the segment's
        mode holds (one per switch kind). Closures over the segment's constants: the
        right-hand side runs about 16 times a solver step, the switch checks 6 times.
        """
        compiled = _COMPILED_KERNEL[0]
        kernel, constants = ((dyn._lean_acceleration_of, self._lean_constants)
                             if compiled is None else
                             (compiled.lean_acceleration, self._lean_array))
        ram_motion = self._ram_motion
        motor = self._motor
        command, reference_end, segment_reference = (self._speed_command, self._reference_end,
                                                     self._segment_reference)
        target, offset_end, segment_offset = (self._offset_command, self._offset_end,
                                              self._segment_offset)
        acceleration_limit, rate_limit = self._acceleration_limit, self._offset_rate_limit
        start, rate, load, saturation = (self._segment_start, self._offset_rate, self._load,
                                         self._saturation)
        stiffness, limit = (0.0, 0.0) if motor is None else (motor.speed_stiffness,
                                                             motor.max_torque)
        direction, spin, half_work = self._direction, self._spin, self._half_work
        switch_angles = (self._switch_angles(segment_offset) if spin and rate == 0.0
                         else None)
        work_sign = 1 if self._in_work else -1
        cutting = self._loads.cutting_force > 0.0

        def reference_at(time):  # ramping (the callers check time < reference_end themselves)
            return _ramp(segment_reference, command, acceleration_limit, time - start)[0]

        def offset_at(time):  # ramping (the callers check time < offset_end themselves)
            return _ramp(segment_offset, target, rate_limit, time - start)[0]

        held_torque = saturation * limit if saturation else 0.0  # saturated, or no motor
        free = motor is not None and not saturation  # the torque follows the speed law

        def acceleration(time, angle, speed):
            if free:
                reference = command if time >= reference_end else reference_at(time)
                torque = stiffness * (reference - speed)
            else:
                torque = held_torque
            offset = target if time >= offset_end else offset_at(time)
            return kernel(constants, offset, angle, speed, rate, torque, load)

        # The solver's times are never before the segment's start: with both ramps ended by
        # then, the reference is the command and the offset its target throughout, and the
        # right-hand side is acceleration's steady branch, written out.
        if max(reference_end, offset_end) > start:
            def rhs(time, y):
                """Right-hand side for DOP853 (y an array: its values go on as floats)."""
                angle, speed = y.tolist()
                return [speed, acceleration(float(time), angle, speed)]
        elif free:
            def rhs(time, y):
                angle, speed = y.tolist()
                return [speed, kernel(constants, target, angle, speed, rate,
                                      stiffness * (command - speed), load)]
        else:
            def rhs(time, y):
                angle, speed = y.tolist()
                return [speed, kernel(constants, target, angle, speed, rate, held_torque,
                                      load)]

        def switching(time, angle, speed, ram=True):
            """ram=False: 1.0 for the ram's two (a step clear of the load's switches)."""
            if motor is None:
                torque_margin = 1.0
            else:
                reference = command if time >= reference_end else reference_at(time)
                demand = stiffness * (reference - speed)
                torque_margin = (limit - abs(demand) if saturation == 0
                                 else saturation * demand - limit)
            if not ram:
                return [1.0, 1.0, torque_margin, spin * speed]
            offset = target if time >= offset_end else offset_at(time)
            position, velocity = ram_motion(offset, angle, speed, rate)
            return [direction * velocity,
                    (half_work - abs(position)) * work_sign if cutting else 1.0,
                    torque_margin, spin * speed]

        def clear(low, high):
            """Say whether the angles low..high (rad) keep the margin from the load's switches."""
            if switch_angles is None:
                return False
            width = high - low + 2.0 * _SWITCH_ANGLE_MARGIN
            low = (low - _SWITCH_ANGLE_MARGIN) % TWO_PI
            index = bisect.bisect_left(switch_angles, low)
            following = (switch_angles[index] if index < len(switch_angles)
                         else switch_angles[0] + TWO_PI)  # the next switch up from low
            return following - low > width

        def motor_holds(start, low, high):
            """
            Say whether the motor's switching function is > 0 at all speeds low..high (rad/s).

            From start (s) on with the reference at its command: the function is then
            monotonic in the speed, in floating point too, so its ends bound it.
            """
            if motor is None:
                return True
            if start < reference_end:
                return False
            for speed in (low, high):
                demand = stiffness * (command - speed)
                if not (limit - abs(demand) if saturation == 0
                        else saturation * demand - limit) > 0.0:
                    return False
            return True

        return rhs, acceleration, switching, clear, motor_holds

    def _switch_angles(self, offset):
        """Input angles (rad, in [0, 2 pi)) of the load's switches at this offset (cached)."""
        if self._switch_angles_at[:2] != (offset, self._loads):
            angles = _load_switch_angles(self._geometry, self._loads, offset)
            self._switch_angles_at = (offset, self._loads,
                                      sorted(float(angle) % TWO_PI for angle in angles))
        return self._switch_angles_at[2]

    def _set_ramp_ends(self, time, reference, offset):
        """When (s) the reference and the offset reach their commands: kinks to stop at."""
        gap = self._speed_command - reference
        self._reference_end = time + abs(gap) / self._acceleration_limit if gap else -math.inf
        gap = self._offset_command - offset
        self._offset_end = time + abs(gap) / self._offset_rate_limit if gap else -math.inf

    def _breakpoint(self, time):
        """Next time (s) a ramp ends after time, where the right-hand side has a kink."""
        ends = [end for end in (self._reference_end, self._offset_end) if end > time]
        return min(ends, default=math.inf)

    def _start(self, time, angle, speed, reference, offset, trigger):
        """Start a segment at time with this state; choose its mode from the state."""
        self._acceleration_now = None
        self._pending = None  # a command's restart from the present stamp replaces it
        self._ahead.clear()  # and the pieces made ahead of the stamps
        old_rate = self._offset_rate
        gap = self._offset_command - offset
        rate = math.copysign(self._offset_rate_limit, gap) if gap else 0.0
        self._segment_start, self._segment_reference, self._segment_offset = (
            time, reference, offset)
        self._set_ramp_ends(time, reference, offset)
        angle = wrap_angle(angle)
        if rate != old_rate:
            # An impulse on the offset alone keeps the input's generalised momentum.
            chain = self._chain(offset, angle, speed, old_rate)
            speed -= chain.offset_coupling_inertia * (rate - old_rate) / (
                chain.generalized_inertia)
        self._offset_rate = rate
        chain = self._chain(offset, angle, speed, rate)
        self._half_work = 0.5 * self._loads.cutting_length
        if trigger is not None and self._spin and (
                _sign(speed) != self._spin
                or (trigger == _DIRECTION and abs(speed) <= _STOP_SPEED)):
            # Another switch landed where the speed is through zero (the load's reversal
            # and the shaft's coincide when the shaft stops): that is a stop first.
            trigger = _SPIN
        if trigger == _SPIN:
            speed = 0.0
            chain = self._chain(offset, angle, speed, rate)
        old_direction = getattr(self, '_direction', 1)
        velocity = chain.ram_velocity
        if trigger == _DIRECTION:
            self._direction = -old_direction
        else:
            self._direction = _sign(velocity) or _sign(chain.ram_lever_arm * speed) or 1
        if trigger == _WORK:
            self._in_work = not self._in_work
        else:
            self._in_work = abs(chain.ram_position) <= self._half_work
        self._stall_reason = None
        self._spin = _sign(speed)
        if self._spin == 0:
            self._at_rest(chain, angle, reference, velocity)
        if trigger == _SATURATION:
            demand = self._motor.speed_stiffness * (reference - speed)
            self._saturation = 0 if self._saturation else _sign(demand)
        else:
            self._saturation = self._saturation_of(reference, speed)
        self._load = self._loaded(self._direction, self._in_work)
        self._angle, self._speed = angle, speed
        if self._spin == 0:
            self._solver = None
            self._piece = (time, math.inf, None)
            return
        # The segment's functions (not at rest: _start runs every tick while held).
        (rhs, self._acceleration_at, self._switching, self._clear,
         self._motor_holds) = self._segment_functions()
        self._solver = _Dop853(rhs, time, [angle, speed], self._breakpoint(time))
        # The last piece stays valid up to here (a stamp just before the switch), no further.
        piece_start, _, at = self._piece
        self._piece = (piece_start, time, at) if at is not None else (time, time, None)

    def _saturation_of(self, reference, speed):
        if self._motor is None:
            return 0
        demand = self._motor.speed_stiffness * (reference - speed)
        return _sign(demand) if abs(demand) >= self._motor.max_torque else 0

    def _at_rest(self, chain, angle, reference, velocity):
        """Input speed zero: pick the direction the torques allow, or hold (the stall rule)."""
        torque = self._motor_torque(reference, 0.0, self._saturation_of(reference, 0.0))
        accelerations = {}
        for spin in (1, -1):
            direction = _sign(velocity) or _sign(chain.ram_lever_arm * spin) or spin
            load = self._loaded(direction, self._in_work)
            accelerations[spin] = (self._acceleration(chain, torque, load), direction)
        for spin in (1, -1):
            acceleration, direction = accelerations[spin]
            if acceleration * spin > 0.0:
                self._spin, self._direction = spin, direction
                return
        self._spin = 0
        if reference != 0.0 or self._speed_command != 0.0:
            needed = chain.generalized_inertia * -accelerations[_sign(reference) or 1][0] + torque
            self._stall_reason = (
                f'stalled at input angle {angle:.6g} rad: the motor gives {torque:.6g} N*m at '
                f'zero speed (max_torque '
                f'{self._motor.max_torque if self._motor else 0.0:.6g} N*m), the load needs '
                f'{needed:.6g} N*m to turn the input (cutting_force '
                f'{self._loads.cutting_force:.6g} N, ram_friction '
                f'{self._loads.ram_friction:.6g} N)')

    def _extend(self):
        """Cover the next stretch of time: the next piece made, solver steps, or a restart."""
        ahead = self._ahead
        if ahead:
            self._piece = ahead.popleft()
            return
        if self._pending is not None:
            # The stamps have passed the switch: its segment starts now (not before, so that
            # a stamp just before it reads the mode it is in: load, saturation, direction).
            time, angle, speed, kind = self._pending
            self._start(time, angle, speed, self._reference_at(time), self._offset_at(time),
                        kind)
            return
        solver = self._solver
        if solver.status == 'finished':
            time = float(solver.t)
            angle, speed = solver.y.tolist()
            self._start(time, angle, speed, self._reference_at(time), self._offset_at(time),
                        None)
            return
        for _ in range(_STEPS_AHEAD):
            ahead.append(self._step(solver))
            if self._pending is not None or solver.status == 'finished':
                break
        self._piece = ahead.popleft()

    def _step(self, solver):
        """Take one solver step; return its piece (cut at a switch, then pending)."""
        message = solver.step()
        if solver.status == 'failed':
            raise dyn.DynamicsError(f'the motor-drive integration failed: {message}')
        # Plain floats (numpy's scalars are several times slower in the arithmetic below).
        start, end = float(solver.t_old), float(solver.t)
        dense = solver.dense_output()
        at = _float_dense(dense)
        switch = self._first_switch(at, start, end)
        if switch is None:
            if self._observer is not None:
                self._observer(start, end, dense)
            return start, end, at
        time, kind = switch
        if self._observer is not None:
            self._observer(start, time, dense)
        angle, speed = at(time)
        self._pending = (time, angle, speed, kind)
        return start, time, at

    def _first_switch(self, at, start, end):
        # np.linspace(start, end, _ROOT_SAMPLES + 1), the same numbers without its overhead.
        step = (end - start) / _ROOT_SAMPLES
        times = [index * step + start for index in range(_ROOT_SAMPLES)] + [end]
        samples = [at(time) for time in times]
        angles, speeds = zip(*samples)
        # With the speed's sign held at every sample, the ram's switching functions change
        # sign only at the load's switch angles.
        low, high = min(speeds), max(speeds)
        held = low > 0.0 if self._spin > 0 else high < 0.0
        ram = not (held and self._clear(min(angles), max(angles)))
        if not ram and self._motor_holds(start, low, high):
            return None  # no switching function goes from > 0 to <= 0 between samples
        switching = self._switching
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

    # Stepping -----------------------------------------------------------------------------

    def integrate_to(self, stamp_ns):
        """Advance the state to stamp_ns (int nanoseconds)."""
        stamp_ns = int(stamp_ns)
        previous = self._stamp_ns
        if previous is None:
            self._new_base(stamp_ns)
            return
        if stamp_ns == previous:
            return
        if stamp_ns < previous:
            self.time_resets += 1
            self._new_base(stamp_ns)
            return
        self._stamp_ns = stamp_ns
        time = (stamp_ns - self._base_ns) / NANOSECONDS_PER_SECOND
        self._time = time
        self._acceleration_now = None
        if self._spin == 0:
            # At rest: the reference may have ramped; re-check the stall rule now.
            self._start(time, self._angle, 0.0, self._reference_at(time),
                        self._segment_offset, None)
            return
        while self._piece[1] < time:
            self._extend()
            if self._spin == 0 and self._piece[1] == math.inf:
                break
        at = self._piece[2]
        if at is None:
            return  # resting, or the segment starts exactly here
        angle, speed = at(time)
        self._angle, self._speed = wrap_angle(angle), speed

    def mechanism_state(self):
        """Return the kinematics core's exact state (MechanismState) at the present stamp."""
        return state(self._geometry, self.offset, self._angle, self._speed,
                     self.input_acceleration, self.offset_rate)

    def advance_to(self, stamp_ns):
        """Step to stamp_ns (int nanoseconds) and return the mechanism's state there."""
        self.integrate_to(stamp_ns)
        return self.mechanism_state()

    def efforts(self):
        """``dynamics.Efforts`` at the present stamp (the motor's torque drives the input)."""
        arguments = (self.offset, self._angle, self._speed, self.input_acceleration,
                     self.offset_rate, self._load)
        compiled = _COMPILED_KERNEL[0]
        if compiled is None:
            return dyn.Efforts(*dyn._lean_efforts_of(self._lean_constants, *arguments))
        return dyn.Efforts(*compiled.lean_efforts(self._lean_array, *arguments))

    # State --------------------------------------------------------------------------------

    @property
    def geometry(self):
        return self._geometry

    @property
    def stamp_ns(self):
        """Stamp of the last step (int ns), or None when the next step starts a time base."""
        return self._stamp_ns

    @property
    def input_angle(self):
        """Input shaft angle, rad, in [-pi, pi)."""
        return self._angle

    @property
    def input_speed(self):
        """Input shaft speed, rad/s."""
        return self._speed

    @property
    def input_acceleration(self):
        """Input shaft acceleration at the present stamp from the equation of motion, rad/s^2."""
        if self._spin == 0:
            return 0.0
        if self._acceleration_now is None:  # once per stamp: the state and efforts need it
            self._acceleration_now = self._acceleration_at(self._time, self._angle, self._speed)
        return self._acceleration_now

    @property
    def motor_torque(self):
        """Torque the motor applies to the input shaft now, N m."""
        reference = self._reference_at(self._time)
        return self._motor_torque(reference, self._speed,
                                  self._saturation_of(reference, self._speed))

    @property
    def ram_load(self):
        """F_ext on the ram in the present segment, N along +x."""
        return self._load

    @property
    def stalled(self):
        return self._stall_reason is not None

    @property
    def stall_reason(self):
        """Why the shaft is held (str) while stalled, else None."""
        return self._stall_reason

    @property
    def offset(self):
        """Coupling offset in force, m."""
        return self._offset_at(self._time)

    @property
    def offset_rate(self):
        """Rate of the coupling offset from the present stamp on, m/s."""
        return self._offset_rate if self._spin else 0.0

    @property
    def speed_reference(self):
        """The motor's speed reference now (the speed command after its ramp), rad/s."""
        return self._reference_at(self._time)

    @property
    def speed_command(self):
        return self._speed_command

    @property
    def offset_command(self):
        return self._offset_command

    @property
    def input_acceleration_limit(self):
        return self._acceleration_limit

    @property
    def offset_rate_limit(self):
        return self._offset_rate_limit


class Simulation(NamedTuple):
    """Sampled trajectory of ``simulate`` (s, rad unwrapped, rad/s, rad/s^2, N m, ...)."""

    time: np.ndarray
    input_angle: np.ndarray
    input_speed: np.ndarray
    input_acceleration: np.ndarray
    motor_torque: np.ndarray
    efforts: dyn.Efforts
    stalled: np.ndarray


def simulate(geometry, mass, loads, motor, offset, input_speed, duration, sample_rate,
             initial_speed=None, input_acceleration_limit=1e6, offset_rate_limit=1.0):
    """
    Run a MotorStepper from angle 0 and sample it at sample_rate (Hz) for duration (s).

    It starts at initial_speed (default input_speed, rad/s); the motor's reference ramps to
    input_speed.

    input_angle is unwrapped (it counts whole turns), for energy and work integrals.
    """
    duration = _positive('duration', duration, 's')
    sample_rate = _positive('sample_rate', sample_rate, 'Hz')
    input_speed = _finite('input_speed', input_speed, 'rad/s')
    start_speed = input_speed if initial_speed is None else initial_speed
    stepper = MotorStepper(geometry, mass, loads, motor, start_speed, offset,
                           input_acceleration_limit, offset_rate_limit)
    stepper.integrate_to(0)
    stepper.set_speed_command(input_speed)
    count = int(math.floor(duration * sample_rate + 1e-9)) + 1
    step_ns = NANOSECONDS_PER_SECOND / sample_rate
    stamps = np.round(np.arange(count) * step_ns).astype(np.int64)
    rows = []
    for stamp in stamps:
        stepper.integrate_to(int(stamp))
        rows.append((stepper.input_angle, stepper.input_speed, stepper.input_acceleration,
                     stepper.motor_torque, *stepper.efforts(), stepper.stalled))
    table = np.array(rows, dtype=float)
    return Simulation(time=stamps / NANOSECONDS_PER_SECOND, input_angle=np.unwrap(table[:, 0]),
                      input_speed=table[:, 1], input_acceleration=table[:, 2],
                      motor_torque=table[:, 3], efforts=dyn.Efforts(*table[:, 4:9].T),
                      stalled=table[:, 9].astype(bool))


# Steady state of speed_fluctuation: when the revolution's start speed is periodic
# (relative), and at most how many revolutions to try. Stamps per revolution that drive the
# stepper (the figures come from its dense output, not from these).
_PERIODIC_TOLERANCE = 1e-10
_MAX_REVOLUTIONS = 200
_DRIVE_STAMPS = 50
# A revolution taking this many times its time at the reference speed is refused.
_SLOWEST_REVOLUTION = 100
# Acceleration samples per piece when looking for the input speed's extremes.
_EXTREMUM_SAMPLES = 5
# Gauss-Legendre nodes per piece: the dense output is of degree 7 in time, so the motor's
# torque times the speed and its square (degree 14) are integrated exactly.
_PIECE_NODES, _PIECE_WEIGHTS = special.roots_legendre(8)


class SpeedFluctuation(NamedTuple):
    """Steady motor-drive running: Cs (1), the revolution's time (s), its PairEfforts."""

    fluctuation: float
    revolution_time: float
    pair_efforts: PairEfforts


class _RevolutionTracker:
    """
    Follow a MotorStepper's pieces of trajectory through one input revolution from angle 0.

    The revolution ends where the angle turned reaches 2 pi (brentq on the dense output).
    The input speed's extremes are at the ends of the pieces (a load switch makes the
    acceleration jump) or where the acceleration from the equation of motion is zero
    (brentq on it along the dense output), so max and min are exact to the integration.
    The motor's work and the integral of its torque squared are Gauss-Legendre sums on each
    piece, exact for the dense output; the offset force's peak is refined (bounded Brent)
    around the largest sample of each piece that comes near the peak so far.
    """

    def __init__(self, stepper):
        self._stepper = stepper
        self.turned = self.work = self.torque_square = self.peak_offset_force = 0.0
        self.end_time = self.end_speed = None
        self.highest, self.lowest = -math.inf, math.inf

    def _take(self, speed):
        self.highest, self.lowest = max(self.highest, speed), min(self.lowest, speed)

    def piece(self, start, end, dense):
        """Take in the piece [start, end] (s) of the segment in force, up to the end."""
        if self.end_time is not None:
            return
        angle_at_start, speed_at_start = (float(value) for value in dense(start))
        self._take(speed_at_start)
        angle_at_end = float(dense(end)[0])
        rest = 2.0 * math.pi - self.turned
        if angle_at_end - angle_at_start >= rest:
            end = optimize.brentq(lambda time: float(dense(time)[0]) - angle_at_start - rest,
                                  start, end, xtol=1e-15, rtol=4 * np.finfo(float).eps)
            self.end_time = end
        self.turned += angle_at_end - angle_at_start
        self._extremes(start, end, dense)
        self._integrals(start, end, dense)

    def _extremes(self, start, end, dense):
        step = (end - start) / _EXTREMUM_SAMPLES
        times = [index * step + start for index in range(_EXTREMUM_SAMPLES)] + [end]
        angles, speeds = dense(times).tolist()
        self._take(speeds[-1])
        if self.end_time is not None:
            self.end_speed = speeds[-1]
        acceleration = self._stepper._acceleration_at
        values = [acceleration(*sample) for sample in zip(times, angles, speeds)]
        for index in range(1, len(times)):
            if values[index - 1] * values[index] < 0.0:
                def rate(time):
                    angle, speed = dense(time)
                    return acceleration(time, float(angle), float(speed))
                root = optimize.brentq(rate, times[index - 1], times[index], xtol=1e-15,
                                       rtol=4 * np.finfo(float).eps)
                self._take(float(dense(root)[1]))

    def _offset_force(self, time, angle, speed):
        stepper = self._stepper
        acceleration = stepper._acceleration_at(time, angle, speed)
        return abs(dyn._chain(*stepper._fixed, stepper._offset_at(time), angle, speed,
                              acceleration, stepper._offset_rate, 0.0,
                              stepper._load).efforts.offset_force)

    def _integrals(self, start, end, dense):
        stepper = self._stepper
        half = 0.5 * (end - start)
        times = [start, *(0.5 * (start + end) + half * _PIECE_NODES).tolist(), end]
        angles, speeds = dense(times).tolist()
        work = square = 0.0
        forces = []
        for index, (time, angle, speed) in enumerate(zip(times, angles, speeds)):
            forces.append(self._offset_force(time, angle, speed))
            if 0 < index <= _PIECE_NODES.size:
                torque = stepper._motor_torque(stepper._reference_at(time), speed,
                                               stepper._saturation)
                work += _PIECE_WEIGHTS[index - 1] * torque * speed
                square += _PIECE_WEIGHTS[index - 1] * torque * torque
        self.work += half * work
        self.torque_square += half * square
        best = int(np.argmax(forces))
        if forces[best] >= (1.0 - _PEAK_CANDIDATE_MARGIN) * self.peak_offset_force:
            low, high = times[max(best - 1, 0)], times[min(best + 1, len(times) - 1)]

            def force(time):
                angle, speed = dense(time)
                return -self._offset_force(time, float(angle), float(speed))
            refined = optimize.minimize_scalar(force, bounds=(low, high), method='bounded',
                                               options={'xatol': 1e-12 * (high - low)})
            forces.append(-float(refined.fun))
        self.peak_offset_force = max(self.peak_offset_force, *forces)


def _revolution(geometry, mass, loads, motor, offset, input_speed, start_speed):
    """
    Run one input revolution from angle 0 at start_speed, the motor's reference input_speed.

    Return its SpeedFluctuation and the speed at its end.
    """
    stepper = MotorStepper(geometry, mass, loads, motor, start_speed, offset, 1.0, 1.0)
    stepper.restore(0, 0.0, start_speed, offset, speed_reference=input_speed)
    tracker = _RevolutionTracker(stepper)
    stepper._observer = tracker.piece
    step_ns = max(1, int(round(2.0 * math.pi / input_speed / _DRIVE_STAMPS
                               * NANOSECONDS_PER_SECOND)))
    stamp = 0
    while tracker.end_time is None:
        stamp += step_ns
        stepper.integrate_to(stamp)
        if stepper.stalled:
            raise dyn.DynamicsError(f'the machine stalls: {stepper.stall_reason}')
        if stamp > _SLOWEST_REVOLUTION * _DRIVE_STAMPS * step_ns:
            raise dyn.DynamicsError(
                f'no whole revolution in {_SLOWEST_REVOLUTION} times the time of one at '
                f'input_speed = {input_speed:.6g} rad/s: the drive cannot keep the shaft '
                'turning forward')
    period = tracker.end_time
    # The motor's torque depends on the speed alone (its law, clipped): its peak is at an
    # extreme of the speed.
    peak_torque = max(abs(stepper._motor_torque(input_speed, speed,
                                                stepper._saturation_of(input_speed, speed)))
                      for speed in (tracker.highest, tracker.lowest))
    figures = PairEfforts(peak_input_torque=peak_torque,
                          rms_input_torque=math.sqrt(tracker.torque_square / period),
                          mean_input_power=tracker.work / period,
                          energy_per_pair=tracker.work,
                          peak_offset_force=tracker.peak_offset_force)
    fluctuation = (tracker.highest - tracker.lowest) / (2.0 * math.pi / period)
    return SpeedFluctuation(float(fluctuation), float(period), figures), tracker.end_speed


def _steady_revolution(geometry, mass, loads, motor, offset, input_speed, start_speed):
    """
    Find the periodic steady state by shooting; return its revolution and start speed.

    The speed one revolution later is a smooth map of the start speed (the system is
    autonomous and periodic in the angle); its fixed point is found by secant steps, with
    a plain revolution whenever a secant step does not halve the mismatch.
    """
    known = []  # (start speed, mismatch)
    speed = start_speed
    for _ in range(_MAX_REVOLUTIONS):
        result, end_speed = _revolution(geometry, mass, loads, motor, offset, input_speed,
                                        speed)
        mismatch = end_speed - speed
        if abs(mismatch) <= _PERIODIC_TOLERANCE * abs(speed):
            return result, speed
        known.append((speed, mismatch))
        speed = end_speed
        if len(known) >= 2:
            (before, miss_before), (last, miss_last) = known[-2:]
            converging = len(known) == 2 or abs(miss_last) <= 0.5 * abs(miss_before)
            if converging and miss_last != miss_before:
                secant = last - miss_last * (last - before) / (miss_last - miss_before)
                if math.isfinite(secant) and secant > 0.0:
                    speed = secant
    raise dyn.DynamicsError(f'no periodic steady state within {_MAX_REVOLUTIONS} '
                            f'revolutions (start speed still changing: {speed:.6g} rad/s)')


def speed_fluctuation(geometry, mass, loads, motor, offset, input_speed):
    """
    Steady-state Cs = (max - min) / mean input speed per revolution under a motor drive.

    The motor's reference is input_speed (rad/s, > 0). The periodic steady state is found by
    shooting on the speed at angle 0 (to 1e-10 relative); in its revolution the extremes of
    the speed are located exactly (ends of the integration's pieces and the acceleration's
    zeros on its dense output), and the revolution's time is exact. The PairEfforts are of
    that revolution, integrated exactly on the dense output.
    """
    input_speed = _positive('input_speed', input_speed, 'rad/s')
    return _steady_revolution(geometry, mass, loads, motor, offset, input_speed,
                              input_speed)[0]


def energy_method_inertia(geometry, mass, loads, offset, input_speed, fluctuation):
    """dynamics.md's energy method: total inertia about Delta E / (Cs w^2)."""
    angles = np.linspace(0.0, 2.0 * math.pi, 4097)
    motion = state(geometry, offset, angles, input_speed)
    load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                              geometry.ram_stroke)
    torque = dyn.efforts(geometry, mass, offset, angles, input_speed,
                         external_ram_force=load).input_torque
    excess = integrate.cumulative_trapezoid(torque - np.mean(torque), angles, initial=0.0)
    return float(np.ptp(excess)) / (fluctuation * input_speed ** 2)


def input_inertia_for_speed_fluctuation(geometry, mass, loads, motor, offset, input_speed,
                                        fluctuation):
    """
    Return the input_inertia (kg m^2) that gives the steady Cs fluctuation under the motor.

    input_inertia is the input side's total (rotor, gearbox, an added flywheel); mass's
    other fields are kept.

    Starts from the energy method and solves Cs(input_inertia) = fluctuation by simulation
    (brentq on fluctuation / Cs - 1, nearly linear in the inertia since Cs falls about as
    1 / inertia; to 1e-6 relative in the inertia). Each simulation starts from the periodic
    speed of the nearest inertia already run. A target above what the smallest inertia
    gives, or not > 0, is refused with the reachable range.
    """
    fluctuation = _positive('fluctuation', fluctuation, '(1)')
    input_speed = _positive('input_speed', input_speed, 'rad/s')
    runs = {}  # input_inertia -> (Cs, periodic start speed)

    def fluctuation_at(input_inertia):
        if input_inertia not in runs:
            nearest = min(runs, key=lambda known: abs(known - input_inertia), default=None)
            start = input_speed if nearest is None else runs[nearest][1]
            result, speed = _steady_revolution(
                geometry, dataclasses.replace(mass, input_inertia=input_inertia), loads, motor,
                offset, input_speed, start)
            runs[input_inertia] = (result.fluctuation, speed)
        return runs[input_inertia][0]

    smallest = 0.0 if mass.flywheel_inertia > 0.0 else 1e-6
    largest_reachable = fluctuation_at(smallest)
    if fluctuation >= largest_reachable:
        raise dyn.DynamicsError(
            f'fluctuation = {fluctuation:.6g} is out of range: with input_inertia >= '
            f'{smallest:g} kg*m^2 this drive reaches 0 < Cs < {largest_reachable:.6g}')
    low = smallest
    high = max(energy_method_inertia(geometry, mass, loads, offset, input_speed,
                                     fluctuation), 1e-3)
    while fluctuation_at(high) > fluctuation:
        low, high = high, high * 2.0
    result = optimize.root_scalar(lambda inertia: fluctuation / fluctuation_at(inertia) - 1.0,
                                  bracket=(low, high), method='brentq', rtol=1e-6, xtol=1e-9)
    return float(result.root)
