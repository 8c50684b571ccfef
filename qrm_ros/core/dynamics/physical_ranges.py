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
Bounds a shaper can never leave, for every quantity a user may give.

A finite but absurd value (a 1e308 kg ram, a 5e-324 Hz rate) would pass a check for
finiteness and then overflow somewhere deep in the arithmetic, or make a loop take forever.
These bounds are far outside any shaper that was ever built (a 10 t ram, 10 g of gravity, a
1 MN cutting force), so no real design is refused, and inside them every product the
dynamics forms stays far from overflow. One place for them: the dynamics' parameter sets,
the node's rules and the commands' options all read them here. numpy-free.
"""

import math
from typing import Dict, Optional

from qrm_ros.core.kinematics.geometry import SAFE_OFFSET_FRACTION

__all__ = ['MAX_FLUCTUATION', 'MAX_INPUT_SPEED', 'MAX_MAGNITUDES', 'MIN_FLUCTUATION',
           'MIN_INPUT_SPEED', 'MIN_MOTOR_SPEED_BAND', 'MIN_MOTOR_TIME_CONSTANT',
           'least_input_inertia', 'magnitude_problem', 'motor_speed_band_problem',
           'motor_time_constant', 'motor_time_constant_problem', 'range_problem']

# Largest |value| of each field of the dynamics' parameter sets, in the field's unit.
MAX_MAGNITUDES: Dict[str, float] = {
    'input_inertia': 1e4,        # kg*m^2: a 2 m, 5 t steel flywheel is 2.5e3
    'flywheel_inertia': 1e4,     # kg*m^2
    'lever_inertia': 1e4,        # kg*m^2
    'lever_mass': 1e4,           # kg: 10 t
    'lever_com_distance': 10.0,  # m
    'ram_mass': 1e4,             # kg: 10 t
    'gravity': 100.0,            # m/s^2: about 10 g
    'cutting_force': 1e6,        # N: 1 MN, a heavy planer's cut is about 1e5
    'ram_friction': 1e6,         # N
    'cutting_length': 10.0,      # m (also at most the ram stroke)
    'speed_stiffness': 1e6,      # N*m*s/rad at the input shaft
    'max_torque': 1e6,           # N*m at the input shaft
}

# rad/s: the fastest input shaft (about 95 000 rpm; shapers run at 10-200 rpm), and the
# slowest one a steady figure is worked out for (a turn in 1.7 hours).
MAX_INPUT_SPEED = 1e4
MIN_INPUT_SPEED = 1e-3

# The coefficient of speed fluctuation Cs a flywheel may be sized for (-): below 1e-4 the
# needed inertia is beyond any flywheel (and the simulation's own resolution); above 0.5 the
# speed is no longer a speed with a ripple.
MIN_FLUCTUATION = 1e-4
MAX_FLUCTUATION = 0.5

# s: the shortest mechanical time constant of the motor drive (the input side's inertia over
# the motor's speed stiffness). Its equation of motion is integrated with explicit steps,
# which must be a fraction of this: at 3e-5 s a second of motion costs about half a second
# of computing, at 3e-6 s several seconds, at 1e-12 s (a stiffness of 1e12) years. Real
# drives have milliseconds to seconds (the small shaper's: 3.4 ms; without its input
# inertia, 62 us).
MIN_MOTOR_TIME_CONSTANT = 1e-5

# rad/s: the narrowest speed band in which the motor's torque follows its law before it
# saturates (max_torque / speed_stiffness). A real motor's is its pull-out slip, a few
# percent of its speed; a band narrower than the input speed's round-off would make the
# motor enter and leave saturation at the same instant, for ever.
MIN_MOTOR_SPEED_BAND = 1e-6


def magnitude_problem(name: str, value: float, unit: str) -> Optional[str]:
    """Say why |value| exceeds its field's bound (MAX_MAGNITUDES), or None."""
    bound = MAX_MAGNITUDES.get(name)
    if bound is None or not abs(value) > bound:
        return None
    return (f'{name} = {value!r} {unit} is out of range: a shaper has |{name}| <= {bound:g} '
            f'{unit}')


def motor_time_constant(input_inertia: float, flywheel_inertia: float,
                        speed_stiffness: float) -> float:
    """
    Return the motor drive's shortest mechanical time constant, s.

    The inertia the motor sees is at least input_inertia plus flywheel_inertia times the
    smallest square of the flywheel's speed over the input's. Within the safe offsets
    (|offset| <= SAFE_OFFSET_FRACTION coupling_radius) that ratio is at least
    1 / (1 + SAFE_OFFSET_FRACTION); the lever and the ram only add inertia.
    """
    least_ratio = 1.0 / (1.0 + SAFE_OFFSET_FRACTION)
    return (input_inertia + flywheel_inertia * least_ratio ** 2) / speed_stiffness


def range_problem(name: str, value: float, low: float, high: float, unit: str) -> Optional[str]:
    """Say why value is outside [low, high] (unit), naming both, or None."""
    if low <= value <= high:
        return None
    return f'{name} = {value!r} {unit} is out of range: allowed [{low:g}, {high:g}] {unit}'


def least_input_inertia(flywheel_inertia: float, speed_stiffness: float) -> float:
    """Return the smallest input_inertia (kg m^2) the time constant's floor allows."""
    least_ratio = 1.0 / (1.0 + SAFE_OFFSET_FRACTION)
    return max(0.0, MIN_MOTOR_TIME_CONSTANT * speed_stiffness
               - flywheel_inertia * least_ratio ** 2)


def motor_speed_band_problem(speed_stiffness: float, max_torque: float) -> Optional[str]:
    """Say why the motor saturates within too narrow a speed band, or None."""
    band = max_torque / speed_stiffness
    if band >= MIN_MOTOR_SPEED_BAND or math.isnan(band):
        return None
    return (f'the motor saturates within max_torque / speed_stiffness = {band:.3g} rad/s of '
            f'its reference, below {MIN_MOTOR_SPEED_BAND:g} rad/s: raise motor_max_torque '
            f'(at least {MIN_MOTOR_SPEED_BAND * speed_stiffness:.6g} N*m here) or lower '
            'motor_speed_stiffness')


def motor_time_constant_problem(input_inertia: float, flywheel_inertia: float,
                                speed_stiffness: float) -> Optional[str]:
    """Say why the motor is too stiff for the inertia it drives, or None."""
    constant = motor_time_constant(input_inertia, flywheel_inertia, speed_stiffness)
    if constant >= MIN_MOTOR_TIME_CONSTANT or math.isnan(constant):
        return None
    return (f'the motor drive\'s time constant (input_inertia + flywheel_inertia / '
            f'{(1.0 + SAFE_OFFSET_FRACTION) ** 2:g}) / speed_stiffness = {constant:.3g} s is '
            f'below {MIN_MOTOR_TIME_CONSTANT:g} s: lower motor_speed_stiffness (at most '
            f'{speed_stiffness * constant / MIN_MOTOR_TIME_CONSTANT:.6g} N*m*s/rad here) '
            'or add inertia')
