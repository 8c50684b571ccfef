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
Steady running under the motor drive against independent sampling and path work.

speed_fluctuation against a dense simulation and the loads' path work;
input_inertia_for_speed_fluctuation against a simulation of the inertia it sizes.
"""

import math

import numpy as np
import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry, KinematicsError
from qrm_ros.core.motor.motor_stepper import simulate
from qrm_ros.core.motor.steady_running import (input_inertia_for_speed_fluctuation,
                                               speed_fluctuation)

GEOMETRY = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()


SOFT_MOTOR = dyn.MotorDrive(speed_stiffness=20.0, max_torque=250.0)


def test_flywheel_sizing_gives_the_asked_fluctuation_when_simulated():
    inertia = input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, SOFT_MOTOR, 0.01,
                                                  2 * math.pi, 0.05)
    sized = dyn.MassProperties(**{**MASS.as_dict(), 'input_inertia': inertia})
    # Checked on an independent sampling: simulate at 5 kHz, last whole revolution.
    run = simulate(GEOMETRY, sized, LOADS, SOFT_MOTOR, 0.01, 2 * math.pi, 30.0, 5000.0)
    turns = np.floor(run.input_angle / (2 * math.pi))
    last = (turns == turns[-1] - 1)
    times = run.time[last]
    fluctuation = np.ptp(run.input_speed[last]) / (2 * math.pi / (times[-1] - times[0]))
    assert fluctuation == pytest.approx(0.05, rel=0.01)


def test_unreachable_fluctuation_names_the_reachable_range():
    with pytest.raises(dyn.DynamicsError, match='fluctuation = 0.5 is out of range: .* reaches'):
        input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, dyn.MotorDrive.small_shaper(),
                                            0.01, 2 * math.pi, 0.5)
    # Beyond any flywheel's range, refused before any simulation.
    with pytest.raises(dyn.DynamicsError, match=r'fluctuation = 10.0 \(1\) is out of range: '
                                                r'allowed \[0.0001, 0.5\]'):
        input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, SOFT_MOTOR, 0.01,
                                            2 * math.pi, 10.0)
    with pytest.raises(KinematicsError, match='fluctuation'):
        input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, SOFT_MOTOR, 0.01,
                                            2 * math.pi, -0.1)


@pytest.mark.parametrize('motor, offset', [(SOFT_MOTOR, 0.01),
                                           (dyn.MotorDrive.small_shaper(), -0.015)])
def test_speed_fluctuation_against_dense_sampling_and_path_work(motor, offset):
    steady = speed_fluctuation(GEOMETRY, MASS, LOADS, motor, offset, 2 * math.pi)
    # Independent: simulate at 20 kHz from the reference speed until the start transient is
    # gone (e^-15 of it for the soft motor), then sample the last whole revolution.
    run = simulate(GEOMETRY, MASS, LOADS, motor, offset, 2 * math.pi, 3.5, 20000.0)
    turns = np.floor(run.input_angle / (2 * math.pi))
    last = turns == turns[-1] - 1
    times, speeds = run.time[last], run.input_speed[last]
    assert steady.revolution_time == pytest.approx(times[-1] - times[0], abs=2 / 20000.0)
    sampled = np.ptp(speeds) / (2 * math.pi / steady.revolution_time)
    # Sampled extremes are low by at most about (a step / the speed's time scale)^2.
    assert sampled <= steady.fluctuation * (1 + 1e-9)
    assert sampled == pytest.approx(steady.fluctuation, rel=1e-5)
    # Steady and periodic: the motor's work per revolution is what the loads take on the
    # ram's path (kinetic and potential energy come back to their values).
    path_work = (LOADS.cutting_force * LOADS.cutting_length
                 + LOADS.ram_friction * 2 * GEOMETRY.ram_stroke)
    figures = steady.pair_efforts
    assert figures.energy_per_pair == pytest.approx(path_work, rel=1e-9)
    assert figures.mean_input_power == pytest.approx(path_work / steady.revolution_time,
                                                     rel=1e-9)
    torque = run.motor_torque[last]
    assert figures.peak_input_torque >= np.max(np.abs(torque)) * (1 - 1e-12)
    assert figures.peak_input_torque == pytest.approx(np.max(np.abs(torque)), rel=1e-5)
    rms = math.sqrt(np.trapezoid(torque ** 2, times) / (times[-1] - times[0]))
    assert figures.rms_input_torque == pytest.approx(rms, rel=1e-4)
    force = run.efforts.offset_force[last]
    assert figures.peak_offset_force >= np.max(np.abs(force)) * (1 - 1e-12)
    assert figures.peak_offset_force == pytest.approx(np.max(np.abs(force)), rel=1e-5)


def test_speed_fluctuation_refuses_a_drive_that_cannot_turn_the_shaft():
    weak = dyn.MotorDrive(speed_stiffness=20.0, max_torque=1.0)
    with pytest.raises(dyn.DynamicsError, match='stalls|no whole revolution'):
        speed_fluctuation(GEOMETRY, MASS, LOADS, weak, 0.01, 2 * math.pi)
