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
The motor drive's stepper against independent derivations and against itself.

Energy and work balances, solve_ivp on dynamics' API, the stall rule, and the same numbers
bit for bit whatever the stamps asked, the form of the right-hand side (compiled or Python),
the steps taken ahead and the screening of steps clear of the load's switches.
"""

import math

import numpy as np
import pytest
from scipy import integrate

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.motor import motor_integration
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import input_angle_for_flywheel_angle, reversal_flywheel_angles, state
from qrm_ros.core.motor.motor_equation import EquationOfMotion
from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.motor.motor_stepper import MotorStepper, simulate

GEOMETRY = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()


def _energy(mass, offset, angle, speed):
    """T + V from the kinematics core's velocities (dynamics.md's energies)."""
    motion = state(GEOMETRY, offset, angle, speed)
    return (0.5 * mass.input_inertia * speed ** 2
            + 0.5 * mass.flywheel_inertia * motion.flywheel_speed ** 2
            + 0.5 * mass.lever_inertia * motion.lever_speed ** 2
            + 0.5 * mass.ram_mass * motion.ram_velocity ** 2
            + mass.lever_mass * mass.gravity * mass.lever_com_distance
            * np.cos(motion.lever_angle))


def test_free_running_conserves_energy_over_100_revolutions():
    offset = 0.015
    run = simulate(GEOMETRY, MASS, dyn.Loads.none(), None, offset, 2 * math.pi, 110.0, 20.0)
    assert run.input_angle[-1] > 100 * 2 * math.pi
    energy = _energy(MASS, offset, run.input_angle, run.input_speed)
    assert np.max(np.abs(energy / energy[0] - 1.0)) <= 1e-9
    assert np.all(np.isfinite(run.input_acceleration))


def _path_dissipation(offset, start_angle, end_angle):
    """Work of the loads against the ram's path from start_angle to end_angle (forward)."""
    reversals = [float(input_angle_for_flywheel_angle(GEOMETRY, offset, angle))
                 for angle in reversal_flywheel_angles(GEOMETRY)]
    breaks = [start_angle, end_angle]
    for reversal in reversals:
        turn = math.ceil((start_angle - reversal) / (2 * math.pi))
        angle = reversal + turn * 2 * math.pi
        while angle < end_angle:
            breaks.append(angle)
            angle += 2 * math.pi
    positions = state(GEOMETRY, offset, np.sort(breaks), 1.0).ram_position
    half = 0.5 * LOADS.cutting_length
    work = 0.0
    for before, after in zip(positions[:-1], positions[1:]):
        work += LOADS.ram_friction * abs(after - before)
        if after < before:  # toward -x: cutting inside the workpiece
            work += LOADS.cutting_force * max(0.0, min(before, half) - max(after, -half))
    return work


def test_work_in_equals_energy_change_plus_dissipation():
    # A saturated motor gives a constant torque: its work is that torque times the angle.
    offset, torque = -0.01, 60.0
    motor = dyn.MotorDrive(speed_stiffness=100.0, max_torque=torque)
    run = simulate(GEOMETRY, MASS, LOADS, motor, offset, 1e4, 3.0, 1000.0,
                   initial_speed=2 * math.pi)
    # The reference ramps from the initial speed for 10 ms: from the second sample on, the
    # motor is at its limit.
    assert np.all(run.motor_torque[1:] == torque)
    run = run._replace(input_angle=run.input_angle[1:], input_speed=run.input_speed[1:])
    energy = _energy(MASS, offset, run.input_angle, run.input_speed)
    work_in = torque * (run.input_angle[-1] - run.input_angle[0])
    dissipated = _path_dissipation(offset, run.input_angle[0], run.input_angle[-1])
    assert work_in > 2 * dissipated > 0
    assert energy[-1] - energy[0] + dissipated == pytest.approx(work_in, rel=1e-9)


def _reference_run(mass, loads, motor, offset, reference_speed, initial_speed, duration):
    """solve_ivp (DOP853, events at the load and motor-limit switches) on dynamics' API."""
    stroke = GEOMETRY.ram_stroke

    def mode_at(angle, speed):
        # The load and motor limit just after this state (positions nudged forward).
        ahead = angle + 1e-7 * math.copysign(1.0, speed)
        motion = state(GEOMETRY, offset, ahead, speed)
        load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity, stroke)
        demand = motor.speed_stiffness * (reference_speed - speed)
        return load, float(np.clip(demand, -motor.max_torque, motor.max_torque))

    def right_hand_side(load, saturated):
        def rhs(time, y):
            y = [float(value) for value in y]
            bias = dyn.efforts(GEOMETRY, mass, offset, y[0], y[1],
                               external_ram_force=load).input_torque
            torque = saturated if saturated is not None else (
                motor.speed_stiffness * (reference_speed - y[1]))
            return [y[1], (torque - bias) / dyn.generalized_inertia(GEOMETRY, mass, offset,
                                                                    y[0])]
        return rhs

    def velocity(time, y):
        y = [float(value) for value in y]
        return state(GEOMETRY, offset, y[0], y[1]).ram_velocity

    def edge_high(time, y):
        return state(GEOMETRY, offset, y[0], y[1]).ram_position - 0.5 * loads.cutting_length

    def edge_low(time, y):
        return state(GEOMETRY, offset, y[0], y[1]).ram_position + 0.5 * loads.cutting_length

    def limit(time, y):
        return abs(motor.speed_stiffness * (reference_speed - y[1])) - motor.max_torque

    def event(function, sign):
        def crossing(time, y):
            return function(time, y)
        crossing.terminal = True
        crossing.direction = -sign  # only leaving the present side ends the piece
        return crossing

    functions = [velocity, edge_high, edge_low, limit]
    time, y = 0.0, [0.0, initial_speed]
    times = []
    while time < duration:
        load, torque = mode_at(*y)
        saturated = torque if abs(torque) >= motor.max_torque else None
        ahead = [y[0] + 1e-7 * math.copysign(1.0, y[1]), y[1]]
        events = [event(function, math.copysign(1.0, function(time, ahead)))
                  for function in functions]
        solution = integrate.solve_ivp(right_hand_side(load, saturated), (time, duration), y,
                                       method='DOP853', rtol=1e-13, atol=1e-13, events=events,
                                       dense_output=True)
        times.append((time, solution.t[-1], solution.sol))
        time, y = solution.t[-1], list(solution.y[:, -1])
    return times


def test_forward_dynamics_against_solve_ivp_over_10_revolutions():
    offset = 0.012
    motor = dyn.MotorDrive.small_shaper()
    duration = 10 * 2 * math.pi / (2 * math.pi)
    pieces = _reference_run(MASS, LOADS, motor, offset, 2 * math.pi, 2 * math.pi, duration)
    run = simulate(GEOMETRY, MASS, LOADS, motor, offset, 2 * math.pi, duration, 100.0)
    assert run.input_angle[-1] > 9.5 * 2 * math.pi
    reference = np.empty_like(run.time)
    for index, time in enumerate(run.time):
        for start, end, dense in pieces:
            if start <= time <= end:
                reference[index] = dense(time)[1]
                break
    assert np.max(np.abs(run.input_speed / reference - 1.0)) <= 1e-8


def _stepper(loads=LOADS, motor=None, speed=2 * math.pi):
    motor = dyn.MotorDrive.small_shaper() if motor is None else motor
    return MotorStepper(GEOMETRY, MASS, loads, motor, speed, 0.01, 50.0, 0.01)


def _run(stepper, start_ns, end_ns, step_ns=1_000_000):
    rows = []
    for stamp in range(start_ns, end_ns + 1, step_ns):
        motion = stepper.advance_to(stamp)
        values = (stepper.input_angle, stepper.input_speed, stepper.input_acceleration,
                  stepper.motor_torque, *motion, *stepper.efforts())
        assert all(math.isfinite(value) for value in values)
        rows.append(values)
    return rows


def test_a_cut_the_motor_cannot_carry_stalls_and_resumes():
    heavy = dyn.Loads(cutting_force=20000.0, ram_friction=20.0, cutting_length=0.15)
    stepper = _stepper(heavy)
    _run(stepper, 0, 3_000_000_000)
    assert stepper.stalled
    assert stepper.input_speed == 0.0 and stepper.input_acceleration == 0.0
    assert 'stalled' in stepper.stall_reason and 'cutting_force 20000' in stepper.stall_reason
    held = stepper.input_angle
    _run(stepper, 3_000_000_000, 3_500_000_000)
    assert stepper.stalled and stepper.input_angle == held
    # The motor's torque at zero speed is the same while held; the ram is in the work.
    assert stepper.motor_torque == pytest.approx(250.0)
    stepper.set_dynamics(loads=LOADS)
    _run(stepper, 3_500_000_000, 4_500_000_000)
    assert not stepper.stalled and stepper.stall_reason is None
    assert stepper.input_speed > 1.0
    # Again, and this time a stronger motor frees it.
    stepper.set_dynamics(loads=heavy)
    _run(stepper, 4_500_000_000, 7_500_000_000)
    assert stepper.stalled
    stepper.set_dynamics(motor=dyn.MotorDrive(speed_stiffness=360.0, max_torque=5000.0))
    _run(stepper, 7_500_000_000, 8_500_000_000)
    assert not stepper.stalled and stepper.input_speed > 1.0


def test_stopped_by_command_is_not_a_stall():
    stepper = _stepper()
    stepper.advance_to(0)
    stepper.set_speed_command(0.0)
    _run(stepper, 0, 4_000_000_000)
    assert abs(stepper.input_speed) < 1e-6 or stepper.input_speed == 0.0
    assert not stepper.stalled


def test_same_commands_same_stamps_bit_identical_and_independent_of_the_stamps_asked():
    def commanded(step_ns):
        stepper = _stepper()
        rows = _run(stepper, 0, 500_000_000, step_ns)
        stepper.set_offset_command(-0.012)
        stepper.set_speed_command(9.0)
        rows += _run(stepper, 500_000_000, 2_000_000_000, step_ns)
        return rows

    fine = commanded(1_000_000)
    assert fine == commanded(1_000_000)
    coarse = commanded(100_000_000)
    # Stamps every 100 ms are every 100th of the 1 ms run: the same numbers, bit for bit.
    assert coarse == fine[:501:100] + fine[501::100]


def test_time_reset_and_restore():
    stepper = _stepper()
    _run(stepper, 10_000_000, 200_000_000)
    angle, speed = stepper.input_angle, stepper.input_speed
    stepper.advance_to(5_000_000)
    assert stepper.time_resets == 1
    assert (stepper.input_angle, stepper.input_speed) == (angle, speed)
    twin = _stepper()
    twin.restore(5_000_000, angle, speed, stepper.offset, stepper.speed_reference)
    assert _run(twin, 5_000_000, 300_000_000) == _run(stepper, 5_000_000, 300_000_000)


def _bits(values):
    return [float(value).hex() for value in values]


def _chain_fixed(mass):
    """The chain's fixed arguments on floats, as the stepper holds them (motor_equation)."""
    return (dyn.SCALAR_OPS, *dyn.geometry_fields(GEOMETRY), mass.scalars())


def _kernel():
    pytest.importorskip('numba')
    from qrm_ros.core.dynamics import drive_kernel
    return drive_kernel


def _commanded_run(loads, at_tick=None):
    """A run with ramps, an offset change and a reversal; at_tick(stamp_ns) before each."""
    stepper = _stepper(loads)
    rows = []
    for start, end, step, change in (
            (0, 1_500_000_000, 1_000_000, None),
            (1_500_000_000, 3_000_000_000, 700_001,
             lambda: (stepper.set_offset_command(-0.012), stepper.set_speed_command(12.0))),
            (3_000_000_000, 5_500_000_000, 1_300_000, lambda: stepper.set_speed_command(-4.0))):
        if change is not None:
            change()
        for stamp in range(start, end + 1, step):
            if at_tick is not None:
                at_tick(stamp)
            rows += _run(stepper, stamp, stamp)
    return rows


@pytest.mark.parametrize('cutting_force', [LOADS.cutting_force, 6000.0])  # 6000: saturates
def test_the_compiled_and_python_right_hand_sides_give_the_same_run(monkeypatch, cutting_force):
    # The stepper takes the compiled forms up when its loading thread is done (the right-hand
    # side at the next segment, the efforts at once): runs in either form, or switching
    # mid-run, are the same bit for bit.
    compiled = _kernel()
    loads = dyn.Loads(cutting_force=cutting_force, ram_friction=LOADS.ram_friction,
                      cutting_length=LOADS.cutting_length)
    monkeypatch.setattr(COMPILED_DRIVE_KERNEL, 'module', compiled)
    in_compiled = _commanded_run(loads)
    COMPILED_DRIVE_KERNEL.module = None
    in_python = _commanded_run(loads)
    assert in_python == in_compiled

    def load_at_two_seconds(stamp):
        COMPILED_DRIVE_KERNEL.module = compiled if stamp >= 2_000_000_000 else None
    assert _commanded_run(loads, load_at_two_seconds) == in_compiled


@pytest.mark.parametrize('cutting_force', [LOADS.cutting_force, 6000.0])
def test_steps_taken_ahead_of_the_stamps_change_nothing(monkeypatch, cutting_force):
    loads = dyn.Loads(cutting_force=cutting_force, ram_friction=LOADS.ram_friction,
                      cutting_length=LOADS.cutting_length)
    ahead = _commanded_run(loads)
    monkeypatch.setattr(motor_integration, 'STEPS_AHEAD', 1)
    assert _commanded_run(loads) == ahead


def test_without_numba_the_stepper_runs_the_python_form(monkeypatch):
    import builtins
    real_import = builtins.__import__

    def without_numba(name, *arguments, **options):
        if name == 'numba' or name.startswith('numba.') or (
                name == 'qrm_ros.core.dynamics' and 'drive_kernel' in (arguments[2] or ())):
            raise ImportError(f'no module named {name!r} (test)')
        return real_import(name, *arguments, **options)
    monkeypatch.setattr(COMPILED_DRIVE_KERNEL, 'module', None)
    monkeypatch.setattr(builtins, '__import__', without_numba)
    COMPILED_DRIVE_KERNEL.load()
    assert COMPILED_DRIVE_KERNEL.module is None and COMPILED_DRIVE_KERNEL.loaded.is_set()
    monkeypatch.setattr(builtins, '__import__', real_import)
    rows = _run(_stepper(), 0, 200_000_000)
    assert rows[-1][1] > 0.0


@pytest.mark.parametrize('cutting_force, cutting_length', [
    (LOADS.cutting_force, LOADS.cutting_length), (LOADS.cutting_force, GEOMETRY.ram_stroke),
    (6000.0, LOADS.cutting_length)])  # the last: the motor saturates, then the shaft stalls
def test_steps_clear_of_the_load_switches_find_the_same_switches(monkeypatch, cutting_force,
                                                                 cutting_length):
    # The stepper skips the switching functions on steps whose angles stay clear of the load's
    # switch angles (and whose speeds keep the motor's mode); without that screening every
    # sample is checked. The same numbers.
    loads = dyn.Loads(cutting_force=cutting_force, ram_friction=LOADS.ram_friction,
                      cutting_length=cutting_length)

    def commanded():
        stepper = _stepper(loads)
        rows = _run(stepper, 0, 1_500_000_000)
        stepper.set_offset_command(-0.012)
        stepper.set_speed_command(12.0)
        rows += _run(stepper, 1_500_000_000, 3_000_000_000, 700_001)
        stepper.set_speed_command(-4.0)
        rows += _run(stepper, 3_000_000_000, 5_500_000_000, 1_300_000)
        return rows

    screened = commanded()
    monkeypatch.setattr(EquationOfMotion, 'switch_angles', lambda self, offset: None)
    assert commanded() == screened


def test_a_change_while_held_applies_to_the_held_state():
    stepper = _stepper()
    _run(stepper, 0, 300_000_000)
    stepper.resync()
    other = dyn.MassProperties(input_inertia=0.05, flywheel_inertia=0.0, lever_mass=3.0,
                               lever_inertia=0.4, lever_com_distance=0.2, ram_mass=12.0)
    stepper.set_dynamics(mass=other)
    chain = dyn.evaluate_chain(*_chain_fixed(other), stepper.offset, stepper.input_angle,
                               stepper.input_speed, 0.0, stepper.offset_rate, 0.0, 0.0)
    assert stepper.input_acceleration == EquationOfMotion.acceleration(
        chain, stepper.motor_torque, stepper.ram_load)


def test_a_stamp_too_far_ahead_is_cut_off_in_bounded_pieces_and_the_state_held():
    """A clock jump of a day: at most MAX_PIECES_PER_STAMP pieces, then the state is held
    and integration goes on from the new stamp (the loop behind the hang once seen)."""
    stepper = _stepper()
    _run(stepper, 0, 100_000_000)
    far = 86_400 * 10 ** 9
    stepper.advance_to(far)
    assert stepper.integration_cutoffs == 1
    assert math.isfinite(stepper.input_angle) and math.isfinite(stepper.input_speed)
    rows = _run(stepper, far, far + 200_000_000, 10_000_000)
    assert stepper.integration_cutoffs == 1 and len(rows) == 21
    assert stepper.input_speed > 1.0  # running on from the held state


@pytest.mark.parametrize('max_torque', [1e-3, 1.0, 30.0])
def test_the_input_effort_stays_within_the_motor_torque_while_braking_and_held(max_torque):
    """A weak motor braked to a stop and held: the input effort is the motor's torque,
    clipped to +-max_torque on every path (it once read -10 N m for a limit of 1e-12)."""
    stepper = _stepper(motor=dyn.MotorDrive(speed_stiffness=360.0, max_torque=max_torque))
    rows = _run(stepper, 0, 1_000_000_000, 5_000_000)
    stepper.set_speed_command(0.0)
    rows += _run(stepper, 1_000_000_000, 6_000_000_000, 5_000_000)
    efforts = [row[-5] for row in rows]  # the input shaft's effort
    assert max(abs(effort) for effort in efforts) <= max_torque * (1 + 1e-12)
