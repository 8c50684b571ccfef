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

import math
from typing import NamedTuple

import numpy as np
from scipy import integrate, optimize

from qrm_ros import dynamics as dyn
from qrm_ros.kinematics import check_offset, KinematicsError, state

__all__ = ['PairEfforts', 'pair_efforts']

# Samples per revolution when looking for switches and peaks (then refined exactly).
_SEARCH_SAMPLES = 2048
_PEAK_SAMPLES = 64  # per smooth piece


class PairEfforts(NamedTuple):
    """Input-side figures of one stroke pair (N m, N m, W, J, N)."""

    peak_input_torque: float
    rms_input_torque: float
    mean_input_power: float
    energy_per_pair: float
    peak_offset_force: float


def _speed(input_speed):
    input_speed = dyn._checked('input_speed', input_speed, 'rad/s')
    if input_speed == 0.0:
        raise KinematicsError('input_speed must be non-zero (rad/s): a stopped shaft has no '
                              'stroke pairs')
    return input_speed


def _load_switch_times(geometry, loads, offset, input_speed, period):
    """Times in (0, period) where the ram load can switch: reversals and workpiece edges."""
    def switching(time):
        motion = state(geometry, offset, input_speed * time, input_speed)
        half = 0.5 * loads.cutting_length
        return (motion.ram_velocity, motion.ram_position - half, motion.ram_position + half)

    times = np.linspace(0.0, period, _SEARCH_SAMPLES + 1)
    switches = []
    for index, values in enumerate(switching(times)):
        changes = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0.0)[0]
        for change in changes:
            switches.append(optimize.brentq(lambda t: switching(t)[index], times[change],
                                            times[change + 1], xtol=1e-15 * period,
                                            rtol=4 * np.finfo(float).eps))
        switches.extend(times[1:-1][values[1:-1] == 0.0])
    return sorted(switches)


def _peak(function, start, end):
    """max |function| over [start, end]: dense samples, then a bounded refinement."""
    times = np.linspace(start, end, _PEAK_SAMPLES)
    values = np.abs(function(times))
    best = int(np.argmax(values))
    peak = float(values[best])
    low, high = times[max(best - 1, 0)], times[min(best + 1, times.size - 1)]
    if high > low:
        result = optimize.minimize_scalar(lambda t: -abs(float(function(t))), bounds=(low, high),
                                          method='bounded',
                                          options={'xatol': 1e-14 * max(abs(end), 1.0)})
        peak = max(peak, -float(result.fun))
    return peak


def pair_efforts(geometry, mass, loads, offset, input_speed):
    """
    Return the input-side ``PairEfforts`` of one revolution under an ideal speed drive.

    The input turns at the constant input_speed (rad/s, non-zero) with the offset (m) fixed;
    energy_per_pair is the work the drive does in the revolution (the integral of the input
    torque over the angle turned), mean_input_power that work over the revolution's time,
    rms_input_torque the root mean square over time.
    """
    offset = float(check_offset(geometry, offset))
    input_speed = _speed(input_speed)
    loads.check_against(geometry.ram_stroke)
    period = 2.0 * math.pi / abs(input_speed)
    bounds = [0.0, *_load_switch_times(geometry, loads, offset, input_speed, period), period]
    energy = square = peak_torque = peak_force = 0.0
    for start, end in zip(bounds[:-1], bounds[1:]):
        if end <= start:
            continue
        middle = state(geometry, offset, input_speed * 0.5 * (start + end), input_speed)
        load = dyn.ram_load_force(loads, middle.ram_position, middle.ram_velocity,
                                  geometry.ram_stroke)

        def piece(time, load=load):
            return dyn.efforts(geometry, mass, offset, input_speed * np.asarray(time),
                               input_speed, external_ram_force=load)

        def torque(time):
            return piece(time).input_torque

        tolerance = {'epsabs': 0.0, 'epsrel': 1e-12, 'limit': 200}
        energy += input_speed * integrate.quad(torque, start, end, **tolerance)[0]
        square += integrate.quad(lambda t: torque(t) ** 2, start, end, **tolerance)[0]
        peak_torque = max(peak_torque, _peak(torque, start, end))
        peak_force = max(peak_force, _peak(lambda t: piece(t).offset_force, start, end))
    return PairEfforts(peak_input_torque=peak_torque,
                       rms_input_torque=math.sqrt(square / period),
                       mean_input_power=energy / period, energy_per_pair=energy,
                       peak_offset_force=peak_force)
