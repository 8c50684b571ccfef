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
"""A new time base under the motor drive keeps the ramps where they are.

A time reset, a pause (resync) and an integration cut-off start a new time base; the offset
and the motor's speed reference in force there must carry on from their values at the last
stamp, not from the segment's start, so that a ramping offset never jumps back.
"""

import math

import pytest
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.motor.motor_stepper import MotorStepper

OFFSET_RATE_LIMIT = 0.01  # m/s: a 10 mm ramp takes a second


def _ramping_stepper():
    """A motor stepper 0.3 s into a ramp of the offset (0.01 -> -0.01 m) and the speed."""
    stepper = MotorStepper(Geometry.paper(), dyn.MassProperties.small_shaper(),
                           dyn.Loads.small_shaper(), dyn.MotorDrive.small_shaper(),
                           2 * math.pi, 0.01, 5.0, OFFSET_RATE_LIMIT)
    stepper.advance_to(1_000_000_000)
    stepper.set_offset_command(-0.01)
    stepper.set_speed_command(4 * math.pi)
    for stamp in range(1_001_000_000, 1_300_000_001, 1_000_000):
        stepper.advance_to(stamp)
    return stepper


def _ramps(stepper):
    return stepper.offset, stepper.speed_reference


def test_a_time_reset_during_a_ramp_keeps_the_offset_and_the_reference():
    stepper = _ramping_stepper()
    before = _ramps(stepper)
    assert before[0] == pytest.approx(0.01 - 0.3 * OFFSET_RATE_LIMIT, abs=1e-12)
    stepper.advance_to(500_000_000)  # the clock went back
    assert stepper.time_resets == 1
    assert _ramps(stepper) == before
    stepper.advance_to(501_000_000)  # and the ramps go on from there at their limits
    assert stepper.offset == pytest.approx(before[0] - 0.001 * OFFSET_RATE_LIMIT, abs=1e-15)
    assert stepper.speed_reference > before[1]


def test_a_pause_during_a_ramp_resumes_from_the_offset_and_reference_in_force():
    stepper = _ramping_stepper()
    before = _ramps(stepper)
    stepper.resync()
    stepper.advance_to(9_000_000_000)  # resumed later: the pause does not count
    assert _ramps(stepper) == before
