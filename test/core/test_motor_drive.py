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
Drive-side figures and the motor drive against independent derivations.

pair_efforts: the work per revolution against the loads' path work in closed form (the cut
once over the workpiece, friction over twice the stroke; gravity and inertia give back what
they take), the RMS and peaks against dense sampling with no splitting at the switches.
"""

import math

import warnings

import numpy as np
import pytest
from scipy import integrate, optimize

from qrm_ros.core import dynamics as dyn
from qrm_ros.core import motor_drive as md
from qrm_ros.core.geometry import Geometry, KinematicsError
from qrm_ros.core.kinematics import input_angle_for_flywheel_angle, reversal_flywheel_angles, state
from synthetic_run import dense_revolution

GEOMETRY = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
# The masses the lean forms are checked with: the small shaper's, and one without a flywheel.
LEAN_MASSES = [MASS, dyn.MassProperties(
    input_inertia=0.05, flywheel_inertia=0.0, lever_mass=3.0, lever_inertia=0.4,
    lever_com_distance=0.2, ram_mass=12.0, gravity=9.81)]
LOADS = dyn.Loads.small_shaper()


def _dense_torques(offset, input_speed, samples=400001):
    return dense_revolution(GEOMETRY, MASS, LOADS, offset, input_speed, samples)


@pytest.mark.parametrize('offset, input_speed', [(0.0, 2 * math.pi), (0.015, 2 * math.pi),
                                                 (-0.01, 3.0), (0.012, -4.0)])
def test_pair_efforts_against_path_work_and_dense_sampling(offset, input_speed):
    figures = md.pair_efforts(GEOMETRY, MASS, LOADS, offset, input_speed)
    # Cutting only happens on the stroke toward -x, which is the cut for a positive speed and
    # the return for a negative one: either way it crosses the workpiece once per pair.
    path_work = (LOADS.cutting_force * LOADS.cutting_length
                 + LOADS.ram_friction * 2 * GEOMETRY.ram_stroke)
    assert figures.energy_per_pair == pytest.approx(path_work, rel=1e-10)
    period = 2 * math.pi / abs(input_speed)
    assert figures.mean_input_power == pytest.approx(path_work / period, rel=1e-10)
    times, torque, force = _dense_torques(offset, input_speed)
    dense_rms = math.sqrt(np.trapezoid(torque ** 2, times) / period)
    # The trapezoid straddles each load jump: an error of about half the jump in torque^2
    # times one sample spacing per jump, ~1e-5 of the mean square here.
    assert figures.rms_input_torque == pytest.approx(dense_rms, rel=2e-5)
    assert figures.peak_input_torque >= np.max(np.abs(torque)) * (1 - 1e-12)
    assert figures.peak_input_torque == pytest.approx(np.max(np.abs(torque)), rel=1e-6)
    assert figures.peak_offset_force >= np.max(np.abs(force)) * (1 - 1e-12)
    assert figures.peak_offset_force == pytest.approx(np.max(np.abs(force)), rel=1e-6)


def test_pair_efforts_free_running_costs_nothing():
    figures = md.pair_efforts(GEOMETRY, MASS, dyn.Loads.none(), 0.01, 5.0)
    assert abs(figures.energy_per_pair) < 1e-9
    assert figures.peak_input_torque > 0.0


def test_pair_efforts_refuses_bad_input():
    with pytest.raises(KinematicsError, match='input_speed'):
        md.pair_efforts(GEOMETRY, MASS, LOADS, 0.0, 0.0)
    with pytest.raises(KinematicsError, match='offset'):
        md.pair_efforts(GEOMETRY, MASS, LOADS, 0.03, 1.0)
    with pytest.raises(dyn.DynamicsError, match='cutting_length'):
        md.pair_efforts(GEOMETRY, MASS, dyn.Loads(1.0, 1.0, 1.0), 0.0, 1.0)


# The former pair_efforts (numbers by scipy's quad, switches by brentq on 2048 samples a
# revolution, peaks by minimize_scalar), kept as the reference of the fast one. It refined
# 64 samples a piece, which missed narrow peaks near the coupling radius by up to 0.5 %; here
# it takes 1024.
_REFERENCE_SWITCH_SAMPLES = 2048
_REFERENCE_PEAK_SAMPLES = 1024


def _reference_switch_times(geometry, loads, offset, input_speed, period):
    def switching(time):
        motion = state(geometry, offset, input_speed * time, input_speed)
        half = 0.5 * loads.cutting_length
        return (motion.ram_velocity, motion.ram_position - half, motion.ram_position + half)

    times = np.linspace(0.0, period, _REFERENCE_SWITCH_SAMPLES + 1)
    switches = []
    for index, values in enumerate(switching(times)):
        changes = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0.0)[0]
        for change in changes:
            switches.append(optimize.brentq(lambda t: switching(t)[index], times[change],
                                            times[change + 1], xtol=1e-15 * period,
                                            rtol=4 * np.finfo(float).eps))
        switches.extend(times[1:-1][values[1:-1] == 0.0])
    return sorted(switches)


def _reference_peak(function, start, end):
    times = np.linspace(start, end, _REFERENCE_PEAK_SAMPLES)
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


def _reference_pair_efforts(geometry, mass, loads, offset, input_speed):
    period = 2.0 * math.pi / abs(input_speed)
    bounds = [0.0, *_reference_switch_times(geometry, loads, offset, input_speed, period),
              period]
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
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', integrate.IntegrationWarning)
            energy += input_speed * integrate.quad(torque, start, end, **tolerance)[0]
            square += integrate.quad(lambda t: torque(t) ** 2, start, end, **tolerance)[0]
        peak_torque = max(peak_torque, _reference_peak(torque, start, end))
        peak_force = max(peak_force, _reference_peak(lambda t: piece(t).offset_force, start,
                                                     end))
    return md.PairEfforts(peak_input_torque=peak_torque,
                          rms_input_torque=math.sqrt(square / period),
                          mean_input_power=energy / period, energy_per_pair=energy,
                          peak_offset_force=peak_force)


def _random_design(rng):
    """A geometry, masses, loads and offset (within the safe range) drawn at random."""
    pivot = rng.uniform(0.08, 0.2)
    geometry = Geometry(coupling_radius=rng.uniform(0.01, 0.05),
                        crank_radius=rng.uniform(0.2, 0.8) * pivot, pivot_distance=pivot,
                        ram_height=rng.uniform(0.1, 0.4),
                        crank_phase=rng.uniform(-1.0, 1.0) if rng.random() < 0.5 else 0.0)
    mass = dyn.MassProperties(
        input_inertia=rng.uniform(0.0, 2.0), flywheel_inertia=rng.uniform(0.01, 1.0),
        lever_inertia=rng.uniform(0.0, 0.5), lever_mass=rng.uniform(0.0, 10.0),
        lever_com_distance=rng.uniform(-0.1, 0.3), ram_mass=rng.uniform(0.0, 50.0))
    # Half the workpieces are as long as the stroke (their edges are the reversals).
    loads = dyn.Loads(cutting_force=rng.choice([0.0, rng.uniform(0.0, 2000.0)]),
                      ram_friction=rng.choice([0.0, rng.uniform(0.0, 100.0)]),
                      cutting_length=geometry.ram_stroke * rng.choice([1.0, rng.random()]))
    offset = rng.uniform(-1.0, 1.0) * geometry.max_safe_offset
    return geometry, mass, loads, offset


def test_pair_efforts_against_the_quad_reference_on_random_designs():
    rng = np.random.default_rng(9)
    for _ in range(24):
        geometry, mass, loads, offset = _random_design(rng)
        speed = rng.uniform(0.5, 20.0)
        for input_speed in (speed, -speed):
            fast = md.pair_efforts(geometry, mass, loads, offset, input_speed)
            reference = _reference_pair_efforts(geometry, mass, loads, offset, input_speed)
            # The work is what is left of a torque that swings both ways: compare it to the
            # revolution's integral of |torque| (at most 2 pi times the RMS torque).
            work_scale = 2 * math.pi * reference.rms_input_torque
            assert fast.energy_per_pair == pytest.approx(reference.energy_per_pair, rel=1e-12,
                                                         abs=1e-12 * work_scale)
            period = 2 * math.pi / speed
            assert fast.mean_input_power == pytest.approx(
                reference.mean_input_power, rel=1e-12, abs=1e-12 * work_scale / period)
            for name in ('rms_input_torque', 'peak_input_torque', 'peak_offset_force'):
                assert getattr(fast, name) == pytest.approx(getattr(reference, name),
                                                            rel=1e-12), name


def test_pair_efforts_finds_narrow_peaks_near_the_coupling_radius():
    # At 0.87 r1 backward the torque peak is narrow: 64 samples a piece missed it by 0.5 %.
    offset, input_speed = -0.87 * GEOMETRY.coupling_radius, -11.8
    figures = md.pair_efforts(GEOMETRY, MASS, LOADS, offset, input_speed)
    times, torque, force = _dense_torques(offset, input_speed, samples=2000001)
    assert figures.peak_input_torque >= np.max(np.abs(torque)) * (1 - 1e-12)
    assert figures.peak_input_torque == pytest.approx(np.max(np.abs(torque)), rel=1e-9)
    assert figures.peak_offset_force >= np.max(np.abs(force)) * (1 - 1e-12)
    assert figures.peak_offset_force == pytest.approx(np.max(np.abs(force)), rel=1e-9)


def test_pair_efforts_near_the_coupling_radius_stays_at_round_off():
    # The torque's own round-off grows as eps r1^2 / (r1 - |offset|)^2: the quadrature stops
    # there instead of halving forever, and the work still closes on the path work.
    path_work = (LOADS.cutting_force * LOADS.cutting_length
                 + LOADS.ram_friction * 2 * GEOMETRY.ram_stroke)
    for fraction in (0.98, -0.999):
        offset = fraction * GEOMETRY.coupling_radius
        figures = md.pair_efforts(GEOMETRY, MASS, LOADS, offset, 5.0)
        round_off = 1e-14 / (1 - abs(fraction)) ** 2
        assert figures.energy_per_pair == pytest.approx(
            path_work, abs=round_off * 2 * math.pi * figures.rms_input_torque)


# Motor drive -------------------------------------------------------------------------------

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
    run = md.simulate(GEOMETRY, MASS, dyn.Loads.none(), None, offset, 2 * math.pi, 110.0,
                      20.0)
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
    run = md.simulate(GEOMETRY, MASS, LOADS, motor, offset, 1e4, 3.0, 1000.0,
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
    run = md.simulate(GEOMETRY, MASS, LOADS, motor, offset, 2 * math.pi, duration, 100.0)
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
    return md.MotorStepper(GEOMETRY, MASS, loads, motor, speed, 0.01, 50.0, 0.01)


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


def test_the_float_dense_output_is_scipys_bit_for_bit():
    solver = integrate.DOP853(lambda time, y: [y[1], -9.0 * math.sin(y[0]) - 0.1 * y[1]],
                              0.0, [0.3, 2.0], 20.0, rtol=md._RTOL, atol=md._ATOL)
    for _ in range(30):
        solver.step()
        dense = solver.dense_output()
        at = md._float_dense(dense)
        times = np.linspace(solver.t_old, solver.t, 17).tolist()
        for time, expected in zip(times, dense(times).T):
            assert _bits(at(time)) == _bits(expected) == _bits(dense(time))


def _chain_fixed(mass):
    """The chain's fixed arguments on floats, as the stepper holds them (motor_drive)."""
    return (dyn._SCALAR_OPS, *dyn._geometry_fields(GEOMETRY), mass.scalars())


def _random_states(seed, count, offset_fraction, angle_span):
    """Yield (offset, offset rate, angle, speed, torque, load), exact zeros among them."""
    rng = np.random.default_rng(seed)
    radius = GEOMETRY.coupling_radius
    for index in range(count):
        offset = (0.0 if index % 5 == 0 else
                  float(rng.uniform(-offset_fraction, offset_fraction)) * radius)
        rate = 0.0 if index % 3 == 0 else float(rng.normal(0.0, 0.02))
        angle, speed = float(rng.uniform(-angle_span, angle_span)), float(rng.normal(0.0, 20.0))
        torque, load = float(rng.normal(0.0, 300.0)), float(rng.normal(0.0, 1500.0))
        yield offset, rate, angle, speed, torque, load


@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_lean_chain_gives_the_chains_numbers_bit_for_bit(mass):
    # The stepper's right-hand side and switch checks: the chain's formula, not a second one.
    stepper = _stepper()
    fixed = _chain_fixed(mass)
    constants = dyn._lean_constants(GEOMETRY, mass)
    ram_motion = dyn._lean_ram_motion(constants)
    for offset, rate, angle, speed, torque, load in _random_states(9, 20000, 0.9, 4.0):
        chain = dyn._chain(*fixed, offset, angle, speed, 0.0, rate, 0.0, 0.0)
        assert _bits([dyn._lean_acceleration_of(constants, offset, angle, speed, rate, torque,
                                                load)]) == _bits(
            [stepper._acceleration(chain, torque, load)])
        assert _bits(ram_motion(offset, angle, speed, rate)) == _bits(
            [chain.ram_position, chain.ram_velocity])


def _kernel():
    pytest.importorskip('numba')
    from qrm_ros.core import motor_kernel
    return motor_kernel


@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_lean_efforts_are_the_chains_bit_for_bit_in_python_and_compiled(mass):
    kernel = _kernel()
    rng = np.random.default_rng(12)
    constants = dyn._lean_constants(GEOMETRY, mass)
    array = np.array(constants)
    fixed = _chain_fixed(mass)
    radius = GEOMETRY.coupling_radius
    for index in range(30000):
        # Exact zeros too (a shaft at rest, no ramp, no load): the signs of zeros agree.
        offset = 0.0 if index % 5 == 0 else float(rng.uniform(-0.99, 0.99)) * radius
        rate = 0.0 if index % 3 == 0 else float(rng.normal(0.0, 0.02))
        speed = 0.0 if index % 7 == 0 else float(rng.normal(0.0, 20.0))
        acceleration = 0.0 if index % 7 == 0 else float(rng.normal(0.0, 50.0))
        load = 0.0 if index % 4 == 0 else float(rng.normal(0.0, 1500.0))
        angle = float(rng.uniform(-40.0, 40.0))
        arguments = (offset, angle, speed, acceleration, rate, load)
        expected = _bits(dyn._chain(*fixed, offset, angle, speed, acceleration, rate, 0.0,
                                    load).efforts)
        assert _bits(dyn._lean_efforts_of(constants, *arguments)) == expected
        assert _bits(kernel.lean_efforts(array, *arguments)) == expected


@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_compiled_acceleration_gives_the_python_forms_numbers_bit_for_bit(mass):
    compiled = _kernel().lean_acceleration
    constants = dyn._lean_constants(GEOMETRY, mass)
    array = np.array(constants)
    for offset, rate, angle, speed, torque, load in _random_states(11, 50000, 0.99, 40.0):
        arguments = (offset, angle, speed, rate, torque, load)
        assert _bits([compiled(array, *arguments)]) == _bits(
            [dyn._lean_acceleration_of(constants, *arguments)])


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
    form = [compiled]
    monkeypatch.setattr(md, '_COMPILED_KERNEL', form)
    in_compiled = _commanded_run(loads)
    form[0] = None
    in_python = _commanded_run(loads)
    assert in_python == in_compiled

    def load_at_two_seconds(stamp):
        form[0] = compiled if stamp >= 2_000_000_000 else None
    assert _commanded_run(loads, load_at_two_seconds) == in_compiled


@pytest.mark.parametrize('cutting_force', [LOADS.cutting_force, 6000.0])
def test_steps_taken_ahead_of_the_stamps_change_nothing(monkeypatch, cutting_force):
    loads = dyn.Loads(cutting_force=cutting_force, ram_friction=LOADS.ram_friction,
                      cutting_length=LOADS.cutting_length)
    ahead = _commanded_run(loads)
    monkeypatch.setattr(md, '_STEPS_AHEAD', 1)
    assert _commanded_run(loads) == ahead


def test_without_numba_the_stepper_runs_the_python_form(monkeypatch):
    import builtins
    real_import = builtins.__import__

    def without_numba(name, *arguments, **options):
        if name == 'numba' or name.startswith('numba.') or (
                name == 'qrm_ros.core' and 'motor_kernel' in (arguments[2] or ())):
            raise ImportError(f'no module named {name!r} (test)')
        return real_import(name, *arguments, **options)
    form = [None]
    monkeypatch.setattr(md, '_COMPILED_KERNEL', form)
    monkeypatch.setattr(builtins, '__import__', without_numba)
    md._load_compiled_kernel()
    assert form == [None] and md._COMPILED_LOADED.is_set()
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
    monkeypatch.setattr(md.MotorStepper, '_switch_angles', lambda self, offset: None)
    assert commanded() == screened


def test_a_change_while_held_applies_to_the_held_state():
    stepper = _stepper()
    _run(stepper, 0, 300_000_000)
    stepper.resync()
    other = dyn.MassProperties(input_inertia=0.05, flywheel_inertia=0.0, lever_mass=3.0,
                               lever_inertia=0.4, lever_com_distance=0.2, ram_mass=12.0)
    stepper.set_dynamics(mass=other)
    chain = dyn._chain(*_chain_fixed(other), stepper.offset, stepper.input_angle,
                       stepper.input_speed, 0.0, stepper.offset_rate, 0.0, 0.0)
    assert stepper.input_acceleration == stepper._acceleration(chain, stepper.motor_torque,
                                                               stepper.ram_load)


SOFT_MOTOR = dyn.MotorDrive(speed_stiffness=20.0, max_torque=250.0)


def test_flywheel_sizing_gives_the_asked_fluctuation_when_simulated():
    inertia = md.input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, SOFT_MOTOR, 0.01,
                                                     2 * math.pi, 0.05)
    sized = dyn.MassProperties(**{**MASS.as_dict(), 'input_inertia': inertia})
    # Checked on an independent sampling: simulate at 5 kHz, last whole revolution.
    run = md.simulate(GEOMETRY, sized, LOADS, SOFT_MOTOR, 0.01, 2 * math.pi, 30.0, 5000.0)
    turns = np.floor(run.input_angle / (2 * math.pi))
    last = (turns == turns[-1] - 1)
    times = run.time[last]
    fluctuation = np.ptp(run.input_speed[last]) / (2 * math.pi / (times[-1] - times[0]))
    assert fluctuation == pytest.approx(0.05, rel=0.01)


def test_unreachable_fluctuation_names_the_reachable_range():
    with pytest.raises(dyn.DynamicsError, match='fluctuation = 10 is out of range: .* reaches'):
        md.input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, SOFT_MOTOR, 0.01,
                                               2 * math.pi, 10.0)
    with pytest.raises(KinematicsError, match='fluctuation'):
        md.input_inertia_for_speed_fluctuation(GEOMETRY, MASS, LOADS, SOFT_MOTOR, 0.01,
                                               2 * math.pi, -0.1)


@pytest.mark.parametrize('motor, offset', [(SOFT_MOTOR, 0.01),
                                           (dyn.MotorDrive.small_shaper(), -0.015)])
def test_speed_fluctuation_against_dense_sampling_and_path_work(motor, offset):
    steady = md.speed_fluctuation(GEOMETRY, MASS, LOADS, motor, offset, 2 * math.pi)
    # Independent: simulate at 20 kHz from the reference speed until the start transient is
    # gone (e^-15 of it for the soft motor), then sample the last whole revolution.
    run = md.simulate(GEOMETRY, MASS, LOADS, motor, offset, 2 * math.pi, 3.5, 20000.0)
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
        md.speed_fluctuation(GEOMETRY, MASS, LOADS, weak, 0.01, 2 * math.pi)
