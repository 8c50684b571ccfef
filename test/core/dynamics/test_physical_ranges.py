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
Finite but absurd values (qrm_ros.core.dynamics.physical_ranges) and the motor stepper's bounds.

Every field of the dynamics' parameter sets has a bound no shaper leaves; the motor's time
constant has a floor derived from the coupling's speed ratio (checked here against the
kinematics); a clock jump far ahead cannot hold the motor stepper for ever; and a held
shaft's input effort is the motor's, within +-max_torque.
"""

import dataclasses
import math

import numpy as np
import pytest
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry, SAFE_OFFSET_FRACTION
from qrm_ros.core.kinematics import state
from qrm_ros.core.motor.motor_stepper import MAX_PIECES_PER_STAMP, MotorStepper
from qrm_ros.core.dynamics.physical_ranges import (MAX_MAGNITUDES, MIN_MOTOR_SPEED_BAND,
                                                   MIN_MOTOR_TIME_CONSTANT, motor_time_constant)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

PAPER = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()
MOTOR = dyn.MotorDrive.small_shaper()
KINDS = {name: kind for kind in (dyn.MassProperties, dyn.Loads, dyn.MotorDrive)
         for name in kind.field_names()}
DEFAULTS = {dyn.MassProperties: MASS, dyn.Loads: LOADS, dyn.MotorDrive: MOTOR}


@pytest.mark.parametrize('name', sorted(MAX_MAGNITUDES))
def test_every_field_refuses_a_finite_absurd_value_and_takes_its_bound(name):
    kind = KINDS[name]
    values = DEFAULTS[kind].as_dict()
    bound = MAX_MAGNITUDES[name]
    with pytest.raises(dyn.DynamicsError) as error:
        kind(**dict(values, **{name: 1e308}))
    assert f'{name} = 1e+308' in str(error.value) and f'<= {bound:g}' in str(error.value)
    kind(**dict(values, **{name: bound}))  # the bound itself is allowed
    # Arrays (design sweeps) are judged element by element.
    with pytest.raises(dyn.DynamicsError, match=name):
        kind(**dict(values, **{name: np.array([bound / 2, bound * 2])}))


def test_the_time_constant_uses_the_slowest_flywheel_speed_of_the_safe_offsets():
    # Independently: the flywheel's speed over the input's, sampled densely over a turn at
    # the safe offsets' ends, is never below 1 / (1 + SAFE_OFFSET_FRACTION).
    angles = np.linspace(-math.pi, math.pi, 200_001)
    least = min(float(state(PAPER, offset, angles, 1.0).flywheel_speed.min())
                for offset in np.linspace(-PAPER.max_safe_offset, PAPER.max_safe_offset, 9))
    assert least == pytest.approx(1.0 / (1.0 + SAFE_OFFSET_FRACTION), rel=1e-9)
    assert motor_time_constant(1.2, 0.08, 360.0) == pytest.approx(
        (1.2 + 0.08 * least ** 2) / 360.0, rel=1e-8)


def test_a_motor_too_stiff_for_its_inertia_is_refused_with_the_stiffness_allowed():
    stiff = dyn.MotorDrive(speed_stiffness=1e6, max_torque=250.0)
    with pytest.raises(dyn.DynamicsError, match=r"time constant .* below 1e-05 s") as error:
        MotorStepper(PAPER, MASS, LOADS, stiff, 2 * math.pi, 0.0, 20.0, 0.005)
    allowed = float(str(error.value).split('at most ')[1].split(' ')[0])
    assert motor_time_constant(MASS.input_inertia, MASS.flywheel_inertia,
                               allowed) == pytest.approx(MIN_MOTOR_TIME_CONSTANT, rel=1e-5)
    # The stiffest motor allowed runs.
    MotorStepper(PAPER, MASS, LOADS, dataclasses.replace(stiff, speed_stiffness=allowed * 0.999),
                 2 * math.pi, 0.0, 20.0, 0.005).integrate_to(1_000_000)


def test_a_clock_jump_far_ahead_is_cut_off_and_the_state_held():
    stepper = MotorStepper(PAPER, MASS, LOADS, MOTOR, 2 * math.pi, 0.0, 20.0, 0.005)
    stepper.integrate_to(10_000_000)
    stepper.integrate_to(10_000_000 + 10 ** 18)  # 31 years: far more than the bound's pieces
    assert stepper.integration_cutoffs == 1
    assert stepper.stamp_ns == 10_000_000 + 10 ** 18
    assert math.isfinite(stepper.input_angle) and math.isfinite(stepper.input_speed)
    # It goes on from the held state as after a pause.
    stepper.integrate_to(10_000_000 + 10 ** 18 + 10_000_000)
    assert stepper.integration_cutoffs == 1 and stepper.input_speed > 0.0
    assert MAX_PIECES_PER_STAMP >= 1000  # a normal tick (1 to 10 pieces) is never cut


def test_a_held_shaft_publishes_the_motor_torque_within_its_limit():
    # Motor stiffness 1e-12 -> 360, torque 1e6 -> 1e-3: it stalls under the cut and holds;
    # what holds it beyond the motor's 1e-3 N m is the ram's friction, so the input's effort
    # is the motor's torque, never the static balance (-1.6 N m here).
    stepper = MotorStepper(PAPER, MASS, LOADS, MOTOR, 2 * math.pi, 0.0, 20.0, 0.005)
    stamp = 0
    schedule = {100: (1e-12, 360.0), 200: (360.0, 360.0), 300: (360.0, 1e6),
                400: (360.0, 1e-3)}
    held = 0
    for tick in range(1500):
        stamp += 10_000_000
        if tick in schedule:
            stiffness, torque = schedule[tick]
            stepper.set_dynamics(motor=dyn.MotorDrive(speed_stiffness=stiffness,
                                                      max_torque=torque))
        stepper.integrate_to(stamp)
        input_torque = stepper.efforts().input_torque
        limit = stepper.segment.equation.motor.max_torque
        assert abs(input_torque) <= limit, (tick, input_torque)
        held += stepper.stalled
    assert held > 500 and 'stalled' in str(stepper.stall_reason)


def test_a_motor_that_saturates_within_the_speed_round_off_is_refused():
    # 1e-12 N m at 360 N m s/rad: the band is 2.8e-15 rad/s, below the speed's round-off;
    # the motor entered and left saturation at one instant for ever (the node hung).
    stepper = MotorStepper(PAPER, MASS, LOADS, MOTOR, 2 * math.pi, 0.0, 20.0, 0.005)
    with pytest.raises(dyn.DynamicsError, match=r'max_torque / speed_stiffness = 2.78e-15 '
                                                r'rad/s .*at least 0.00036 N\*m'):
        stepper.set_dynamics(motor=dyn.MotorDrive(speed_stiffness=360.0, max_torque=1e-12))
    stepper.set_dynamics(motor=dyn.MotorDrive(speed_stiffness=360.0,
                                              max_torque=360.0 * MIN_MOTOR_SPEED_BAND))
    stepper.integrate_to(2 * NANOSECONDS_PER_SECOND)  # returns: the band is resolved
    assert stepper.integration_cutoffs == 0
