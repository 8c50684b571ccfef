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
Steady running under the motor drive: the speed fluctuation and the inertia that sets it.

The motor's reference held, the machine settles into a periodic running: ``speed_fluctuation``
finds it by shooting and gives its Cs and the PairEfforts of its revolution, exact on the
integration's dense output; ``input_inertia_for_speed_fluctuation`` sizes the input side's
inertia for a Cs, from ``energy_method_inertia``'s textbook estimate (doc/dynamics.md).
"""

import dataclasses
import math
from typing import Dict, NamedTuple, Tuple

import numpy as np
from scipy import integrate, optimize

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.common.checks import positive
from qrm_ros.core.numerics.gauss_legendre import gauss_legendre
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import state
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.dynamics.physical_ranges import (least_input_inertia, MAX_FLUCTUATION,
                                                   MAX_INPUT_SPEED, MAX_MAGNITUDES,
                                                   MIN_FLUCTUATION, MIN_INPUT_SPEED, range_problem)
from qrm_ros.core.dynamics.speed_drive import PairEfforts, PEAK_CANDIDATE_MARGIN
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

__all__ = ['energy_method_inertia', 'input_inertia_for_speed_fluctuation', 'SpeedFluctuation',
           'speed_fluctuation']

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
_PIECE_NODES, _PIECE_WEIGHTS = gauss_legendre(8)


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
        self.stop_time = None  # s, the end of the first piece whose speed comes to <= 0

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
        if self.lowest <= 0.0 and self.stop_time is None:
            self.stop_time = end

    def _extremes(self, start, end, dense):
        step = (end - start) / _EXTREMUM_SAMPLES
        times = [index * step + start for index in range(_EXTREMUM_SAMPLES)] + [end]
        angles, speeds = dense(times).tolist()
        self._take(speeds[-1])
        if self.end_time is not None:
            self.end_speed = speeds[-1]
        acceleration = self._stepper.segment.functions.acceleration
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
        plan, functions, equation = self._stepper.segment
        acceleration = functions.acceleration(time, angle, speed)
        return abs(dyn.evaluate_chain(*equation.fixed, plan.offset_at(time), angle, speed,
                                      acceleration, plan.offset_rate, 0.0,
                                      plan.load).efforts.offset_force)

    def _integrals(self, start, end, dense):
        plan, _, equation = self._stepper.segment
        half = 0.5 * (end - start)
        times = [start, *(0.5 * (start + end) + half * _PIECE_NODES).tolist(), end]
        angles, speeds = dense(times).tolist()
        work = square = 0.0
        forces = []
        for index, (time, angle, speed) in enumerate(zip(times, angles, speeds)):
            forces.append(self._offset_force(time, angle, speed))
            if 0 < index <= _PIECE_NODES.size:
                torque = equation.motor_torque(plan.reference_at(time), speed,
                                               plan.saturation)
                work += _PIECE_WEIGHTS[index - 1] * torque * speed
                square += _PIECE_WEIGHTS[index - 1] * torque * torque
        self.work += half * work
        self.torque_square += half * square
        best = int(np.argmax(forces))
        if forces[best] >= (1.0 - PEAK_CANDIDATE_MARGIN) * self.peak_offset_force:
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
    stepper.set_observer(tracker.piece)
    step_ns = max(1, int(round(2.0 * math.pi / input_speed / _DRIVE_STAMPS
                               * NANOSECONDS_PER_SECOND)))
    stamp = 0
    while tracker.end_time is None:
        stamp += step_ns
        stepper.integrate_to(stamp)
        if stepper.stalled:
            raise dyn.DynamicsError(f'the machine stalls: {stepper.stall_reason}')
        if stepper.integration_cutoffs:
            raise dyn.DynamicsError('the motor drive could not be integrated within a bounded '
                                    'effort (a drive too stiff for its inertia)')
        if tracker.lowest <= 0.0 or stepper.input_speed <= 0.0:
            # Stopped or rolling back (the lever swings under gravity and friction): no
            # forward revolution comes, and the swings would take ever more segments. The
            # pieces are made ahead of the stamps: the stamps are taken past the stop, where
            # the stepper's stall rule says why it holds, if it does (whichever the last bits
            # of the state noticed first, the same answer).
            stop = (tracker.stop_time or 0.0) * NANOSECONDS_PER_SECOND
            while not stepper.stalled and stamp <= stop + step_ns:
                stamp += step_ns
                stepper.integrate_to(stamp)
            if stepper.stalled:
                raise dyn.DynamicsError(f'the machine stalls: {stepper.stall_reason}')
            raise dyn.DynamicsError(
                'the machine stalls: the input stops within a revolution (the motor gives at '
                f'most {motor.max_torque:.6g} N*m at the input shaft)')
        if stamp > _SLOWEST_REVOLUTION * _DRIVE_STAMPS * step_ns:
            raise dyn.DynamicsError(
                f'no whole revolution in {_SLOWEST_REVOLUTION} times the time of one at '
                f'input_speed = {input_speed:.6g} rad/s: the drive cannot keep the shaft '
                'turning forward')
    period = tracker.end_time
    # The motor's torque depends on the speed alone (its law, clipped): its peak is at an
    # extreme of the speed.
    equation = stepper.segment.equation
    peak_torque = max(abs(equation.motor_torque(input_speed, speed,
                                                equation.saturation_of(input_speed, speed)))
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


def speed_fluctuation(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                      motor: dyn.MotorDrive, offset: float,
                      input_speed: float) -> 'SpeedFluctuation':
    """
    Steady-state Cs = (max - min) / mean input speed per revolution under a motor drive.

    The motor's reference is input_speed (rad/s, > 0). The periodic steady state is found by
    shooting on the speed at angle 0 (to 1e-10 relative); in its revolution the extremes of
    the speed are located exactly (ends of the integration's pieces and the acceleration's
    zeros on its dense output), and the revolution's time is exact. The PairEfforts are of
    that revolution, integrated exactly on the dense output.
    """
    input_speed = positive('input_speed', input_speed, 'rad/s')
    problem = range_problem('input_speed', input_speed, MIN_INPUT_SPEED, MAX_INPUT_SPEED,
                            'rad/s')
    if problem:
        raise dyn.DynamicsError(problem)
    return _steady_revolution(geometry, mass, loads, motor, offset, input_speed,
                              input_speed)[0]


def energy_method_inertia(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                          offset: float, input_speed: float, fluctuation: float) -> float:
    """dynamics.md's energy method: total inertia about Delta E / (Cs w^2)."""
    angles = np.linspace(0.0, 2.0 * math.pi, 4097)
    motion = state(geometry, offset, angles, input_speed)
    load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                              geometry.ram_stroke)
    torque = dyn.efforts(geometry, mass, offset, angles, input_speed,
                         external_ram_force=load).input_torque
    excess = integrate.cumulative_trapezoid(torque - np.mean(torque), angles, initial=0.0)
    return float(np.ptp(excess)) / (fluctuation * input_speed ** 2)


def input_inertia_for_speed_fluctuation(geometry: Geometry, mass: dyn.MassProperties,
                                        loads: dyn.Loads, motor: dyn.MotorDrive, offset: float,
                                        input_speed: float, fluctuation: float) -> float:
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
    fluctuation = positive('fluctuation', fluctuation, '(1)')
    input_speed = positive('input_speed', input_speed, 'rad/s')
    problem = (range_problem('fluctuation', fluctuation, MIN_FLUCTUATION, MAX_FLUCTUATION, '(1)')
               or range_problem('input_speed', input_speed, MIN_INPUT_SPEED,
                                MAX_INPUT_SPEED, 'rad/s'))
    if problem:
        raise dyn.DynamicsError(problem)
    runs: Dict[float, Tuple[float, float]] = {}  # input_inertia -> (Cs, start speed)

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
    # No stiffer drive than its explicit steps allow (physical_ranges); rounding up by 1e-12
    # keeps the floor's own value from failing its check.
    smallest = max(smallest, least_input_inertia(mass.flywheel_inertia, motor.speed_stiffness)
                   * (1.0 + 1e-12))
    largest_reachable = fluctuation_at(smallest)
    if fluctuation >= largest_reachable:
        raise dyn.DynamicsError(
            f'fluctuation = {fluctuation:.6g} is out of range: with input_inertia >= '
            f'{smallest:g} kg*m^2 this drive reaches 0 < Cs < {largest_reachable:.6g}')
    low = smallest
    high = max(energy_method_inertia(geometry, mass, loads, offset, input_speed,
                                     fluctuation), 1e-3)
    largest = MAX_MAGNITUDES['input_inertia']
    while fluctuation_at(high) > fluctuation:
        if high >= largest:
            raise dyn.DynamicsError(
                f'fluctuation = {fluctuation:.6g} is out of reach: even input_inertia = '
                f'{largest:g} kg*m^2 (the largest a shaper has) gives Cs = '
                f'{fluctuation_at(high):.6g}')
        low, high = high, min(high * 2.0, largest)
    result = optimize.root_scalar(lambda inertia: fluctuation / fluctuation_at(inertia) - 1.0,
                                  bracket=(low, high), method='brentq', rtol=1e-6, xtol=1e-9)
    return float(result.root)
