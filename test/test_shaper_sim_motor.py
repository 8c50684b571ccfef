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
"""The node under the motor drive, over real DDS: switching, fluctuating speed, stalls."""

import math

from qrm_ros.motor_drive import MotorStepper
from qrm_ros.names import DRIVE_STATUS
from qrm_ros.stepping import ShaperStepper
from rclpy.parameter import Parameter

from shaper_harness import NS, run_ticks


def drive_statuses(diagnostics):
    return [m.status[0] for m in diagnostics if m.status[0].name == DRIVE_STATUS]


def test_switching_to_the_motor_keeps_the_state_and_the_speed_then_fluctuates(harness):
    h = harness(spin_shaper=False, cutting_force=400.0, ram_friction=20.0, cutting_length=0.15)
    stamps = run_ticks(h.shaper, 5 * NS, 0.5)
    before = h.shaper.stepper
    angle, speed = before.input_angle, before.input_speed
    assert h.shaper.set_parameters([Parameter('drive', value='motor')])[0].successful
    after = h.shaper.stepper
    assert isinstance(after, MotorStepper)
    assert (after.input_angle, after.input_speed) == (angle, speed)
    run_ticks(h.shaper, stamps[-1], 2.5)
    h.wait_for(lambda: len(h.joint_states) >= 300, what='joint states')
    speeds = [m.velocity[0] for m in h.joint_states[60:]]
    assert all(math.isfinite(v) for m in h.joint_states for v in m.effort)
    # Under load the motor's speed dips and recovers: it is no longer the commanded constant.
    assert max(speeds) - min(speeds) > 1e-3 * abs(speed)
    assert abs(sum(speeds) / len(speeds) - speed) < 0.1 * abs(speed)
    assert h.shaper.set_parameters([Parameter('drive', value='speed')])[0].successful
    assert isinstance(h.shaper.stepper, ShaperStepper)
    result, = h.shaper.set_parameters([Parameter('drive', value='diesel')])
    assert not result.successful and "'speed', 'motor'" in result.reason


def test_a_load_the_motor_cannot_carry_stalls_it_with_an_error_and_it_resumes(harness):
    # 4 kN on a lever arm of about 0.1 m per rad needs some 400 N m; the motor gives 20.
    h = harness(spin_shaper=False, drive='motor', cutting_force=4000.0, ram_friction=20.0,
                cutting_length=0.15, motor_max_torque=20.0)
    stamps = run_ticks(h.shaper, 5 * NS, 3.0)
    h.wait_for(lambda: drive_statuses(h.diagnostics), what='a drive status')
    stalled = drive_statuses(h.diagnostics)[0]
    assert stalled.level == b'\x02' and 'stalled' in stalled.message
    assert h.shaper.stepper.stalled
    assert h.shaper.set_parameters([Parameter('cutting_force', value=100.0)])[0].successful
    run_ticks(h.shaper, stamps[-1], 1.0)
    h.wait_for(lambda: drive_statuses(h.diagnostics)[-1].level == b'\x00',
               what='the stall to end')
    assert not h.shaper.stepper.stalled
    assert all(math.isfinite(v) for m in h.joint_states for v in (*m.position, *m.velocity,
                                                                  *m.effort))
