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
"""The node's drives over real DDS: switching, fluctuating speed, stalls, effort theory."""

import math
import time

import pytest
from qrm_ros.core.measurement.effort_theory import THEORY_FIGURES
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.dynamics.speed_drive import pair_efforts
from qrm_ros.core.motor.steady_running import speed_fluctuation
from qrm_ros.core.common.names import DRIVE_STATUS, STROKE_PAIR_STATUS
from qrm_ros.core.stepping.stepping import ShaperStepper
from rclpy.parameter import Parameter

from shaper_harness import NS, pair_values, run_ticks


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


def pair_reports(diagnostics):
    return [pair_values(m) for m in diagnostics if m.status[0].name == STROKE_PAIR_STATUS]


def tick_until(h, start_ns, predicate, what, timeout=60.0):
    """Tick the node (synthetic stamps, 0.5 s at a time) until predicate holds."""
    deadline, stamp = time.monotonic() + timeout, start_ns
    while not predicate():
        assert time.monotonic() < deadline, f'timed out waiting for {what}'
        stamp = run_ticks(h.shaper, stamp, 0.5)[-1]
    return stamp


def with_theory(diagnostics):
    return [r for r in pair_reports(diagnostics) if r['effort_theory'] == 'steady setting']


def test_speed_drive_pairs_carry_the_exact_effort_theory_once_worked_out(harness):
    h = harness(spin_shaper=False, cutting_force=400.0, ram_friction=20.0, cutting_length=0.15)
    stamp = tick_until(h, 5 * NS, lambda: pair_reports(h.diagnostics), 'a stroke pair')
    # The first pair waits for the background worker: it says so and carries no numbers.
    first = pair_reports(h.diagnostics)[0]
    assert first['effort_theory'].startswith(('pending', 'none: the setting changed'))
    assert not any(f'{name}_theory' in first for name in THEORY_FIGURES)
    tick_until(h, stamp, lambda: with_theory(h.diagnostics), 'a pair with effort theory')
    report = with_theory(h.diagnostics)[0]
    node = h.shaper
    exact = pair_efforts(node.geometry, node.mass, node.loads, report['coupling_offset'],
                         report['input_speed'])
    for name, value in exact._asdict().items():
        assert report[f'{name}_theory'] == value, name
    assert report['speed_fluctuation_theory'] == 0.0
    # Measured at 100 Hz by the trapezoid rule, the energy is the exact work within about
    # (torque jump x speed x step) at each of the four load switches: a few percent.
    assert report['energy_per_pair'] == pytest.approx(exact.energy_per_pair, rel=0.03)
    assert report['peak_input_torque'] == pytest.approx(exact.peak_input_torque, rel=0.03)


def test_a_setting_change_during_a_pair_gets_no_effort_theory(harness):
    h = harness(spin_shaper=False)
    stamp = run_ticks(h.shaper, 5 * NS, 2.3)[-1]
    assert h.shaper.set_parameters([Parameter('ram_mass', value=30.0)])[0].successful
    changed = stamp / NS

    def spanning():
        return [r for r in pair_reports(h.diagnostics)
                if r['pair_start'] < changed < r['pair_end']]
    tick_until(h, stamp, spanning, 'the pair spanning the change')
    assert spanning()[0]['effort_theory'] == 'none: the setting changed during the pair'


def test_motor_drive_pairs_carry_the_steady_speed_fluctuation_theory(harness):
    h = harness(spin_shaper=False, drive='motor', cutting_force=400.0, ram_friction=20.0,
                cutting_length=0.15)
    tick_until(h, 5 * NS, lambda: with_theory(h.diagnostics), 'a pair with effort theory',
               timeout=120.0)
    report = with_theory(h.diagnostics)[0]
    node = h.shaper
    steady = speed_fluctuation(node.geometry, node.mass, node.loads, node.motor,
                               report['coupling_offset'], node.stepper.speed_reference)
    assert report['speed_fluctuation_theory'] == steady.fluctuation
    for name, value in steady.pair_efforts._asdict().items():
        assert report[f'{name}_theory'] == value, name
    # The node's own pairs, measured from its 100 Hz samples, show that fluctuation.
    assert report['speed_fluctuation'] == pytest.approx(steady.fluctuation, rel=0.05)


def test_motor_drive_pairs_are_steady_in_speed_while_the_reference_holds(harness):
    """The shaft's speed fluctuates by nature; steady in speed means the setting held."""
    h = harness(spin_shaper=False, drive='motor', cutting_force=400.0, ram_friction=20.0,
                cutting_length=0.15)
    stamp = tick_until(h, 5 * NS, lambda: len(pair_reports(h.diagnostics)) >= 2,
                       'two stroke pairs', timeout=120.0)
    held = pair_reports(h.diagnostics)
    assert all(r['input_speed_steady'] == 'true' for r in held), held
    assert len({r['input_speed'] for r in held}) > 1  # the speed does fluctuate
    # A speed command ramps the reference: the pairs it spans are not steady in speed.
    assert h.shaper.set_parameters([Parameter('input_speed', value=3 * math.pi)])[0].successful
    ramp_start = stamp / NS
    ramp_end = ramp_start + math.pi / h.shaper.stepper.input_acceleration_limit

    def spanning():
        return [r for r in pair_reports(h.diagnostics)
                if r['pair_start'] < ramp_end and r['pair_end'] > ramp_start]
    tick_until(h, stamp, lambda: spanning() and pair_reports(h.diagnostics)[-1]['pair_start']
               > ramp_end, 'a pair after the ramp', timeout=120.0)
    assert all(r['input_speed_steady'] == 'false' for r in spanning())
    assert pair_reports(h.diagnostics)[-1]['input_speed_steady'] == 'true'
