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
Flywheel sizing for ``qrm_design flywheel`` (pure numpy/scipy, no ROS).

The sizing itself is steady_running's (``input_inertia_for_speed_fluctuation``): it sizes J1,
the input side's total inertia (motor rotor and gearbox referred to the input shaft, the
input shaft and coupling, and any flywheel added there). This module puts it in a designer's
terms: what J1 must be added to the given one, what the textbook energy method would have
said, the Cs the answer gives when simulated again, and the flywheel J2 on the crank shaft
that would do the same job with J1 kept.

J2 turns with the crank, at d(phi)/d(theta) times the input speed, so it adds
J2 (d(phi)/d(theta))^2 to the generalised inertia M (dynamics.md). Its equivalent is the
J2 that adds as much to M's mean over a revolution as the J1 to be added:
delta J2 = delta J1 / mean((d(phi)/d(theta))^2). At offset 0, d(phi)/d(theta) = 1 and the two
are the same machine; with an offset the flywheel's own speed swings every revolution, so the
equivalent is only an estimate, and its Cs is simulated and reported beside it.
"""

import dataclasses
import math
from typing import NamedTuple, Optional

import numpy as np

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.motor import steady_running

__all__ = ['FlywheelSizing', 'revolution_mean_inertia', 'size_flywheel']

# Samples of a revolution for means of M: a smooth periodic function, so the rectangle rule
# on a uniform grid converges faster than any power of the step.
_MEAN_SAMPLES = 4096


class FlywheelSizing(NamedTuple):
    """What ``size_flywheel`` found (kg m^2 for inertias, 1 for Cs; None: not applicable)."""

    speed_fluctuation: float  # the Cs asked for
    given_speed_fluctuation: float  # steady Cs with the given mass properties
    input_inertia: float  # J1 giving the asked Cs, refined by simulation
    added_input_inertia: float  # input_inertia minus the given J1 (< 0: less is needed)
    simulated_speed_fluctuation: float  # Cs simulated again with input_inertia
    energy_method_inertia: float  # Delta E / (Cs w^2): total equivalent inertia
    chain_mean_inertia: float  # mean over a revolution of M - J1 with the given masses
    energy_method_input_inertia: float  # energy_method_inertia - chain_mean_inertia
    flywheel_mean_square_ratio: float  # mean over a revolution of (d(phi)/d(theta))^2
    equivalent_flywheel_inertia: Optional[float]  # J2 doing the job with J1 kept (None: < 0)
    equivalent_speed_fluctuation: Optional[float]  # Cs simulated with that J2


def revolution_mean_inertia(geometry: Geometry, mass: dyn.MassProperties,
                            offset: float) -> float:
    """Mean of the generalised inertia M over one input revolution at a fixed offset, kg m^2."""
    angles = np.linspace(0.0, 2.0 * math.pi, _MEAN_SAMPLES, endpoint=False)
    return float(np.mean(dyn.generalized_inertia(geometry, mass, offset, angles)))


def size_flywheel(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                  motor: dyn.MotorDrive, offset: float, input_speed: float,
                  fluctuation: float) -> FlywheelSizing:
    """
    Size the input side for a steady Cs under the motor; return a ``FlywheelSizing``.

    offset (m) is fixed, input_speed (rad/s, > 0) is the motor's speed reference. A Cs the
    drive cannot reach, a stall and bad numbers raise DynamicsError or KinematicsError with
    the reason (steady_running's messages).
    """
    input_inertia = steady_running.input_inertia_for_speed_fluctuation(
        geometry, mass, loads, motor, offset, input_speed, fluctuation)

    def fluctuation_with(changed):
        return steady_running.speed_fluctuation(geometry, changed, loads, motor, offset,
                                                input_speed).fluctuation

    given = fluctuation_with(mass)
    simulated = fluctuation_with(dataclasses.replace(mass, input_inertia=input_inertia))
    total = steady_running.energy_method_inertia(geometry, mass, loads, offset, input_speed,
                                                 fluctuation)
    chain = revolution_mean_inertia(geometry, mass, offset) - mass.input_inertia
    unit_flywheel = dyn.MassProperties(input_inertia=0.0, flywheel_inertia=1.0,
                                       lever_inertia=0.0, lever_mass=0.0,
                                       lever_com_distance=0.0, ram_mass=0.0)
    mean_square_ratio = revolution_mean_inertia(geometry, unit_flywheel, offset)
    added = input_inertia - mass.input_inertia
    flywheel = mass.flywheel_inertia + added / mean_square_ratio
    equivalent = equivalent_fluctuation = None
    if flywheel >= 0.0 and mass.input_inertia + flywheel > 0.0:
        equivalent = flywheel
        equivalent_fluctuation = fluctuation_with(
            dataclasses.replace(mass, flywheel_inertia=flywheel))
    return FlywheelSizing(
        speed_fluctuation=float(fluctuation), given_speed_fluctuation=given,
        input_inertia=input_inertia, added_input_inertia=added,
        simulated_speed_fluctuation=simulated, energy_method_inertia=total,
        chain_mean_inertia=chain, energy_method_input_inertia=total - chain,
        flywheel_mean_square_ratio=mean_square_ratio, equivalent_flywheel_inertia=equivalent,
        equivalent_speed_fluctuation=equivalent_fluctuation)
