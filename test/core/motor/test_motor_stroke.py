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
The motor drive with the stroke screw moving the crank pin: r(t) in the equation of motion.

Independent routes: the stepper's input acceleration against Lagrange's equation for the
input angle derived symbolically (sympy) from T and V of doc/dynamics.md, with r(t) the
stroke's ramp through r = S h / sqrt(4 H^2 + S^2) differentiated by sympy too; the stepper's
speed and acceleration against numerical derivatives of its angle and speed; the published
ram velocity against the derivative of the ram's positions; the power balance (motor, screw
and load work against the change of T + V) over a stroke change; the input's generalised
momentum across the instants the screw starts and stops.
"""

import math

import numpy as np
import pytest
from scipy import integrate
import sympy

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke, Geometry
from qrm_ros.core.dynamics.lean_chain import lean_constants
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.motor.motor_stroke import moving_radius_motion_of
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp
from qrm_ros.core.dynamics.stroke_efforts import lever_radius_coefficient

from lagrange_chain import chain_lagrangian, generalised_forces

PAPER = Geometry.paper()
R1, H_PIVOT, RAM_HEIGHT = 0.025, 0.113, 0.2
MASS = dyn.MassProperties(input_inertia=0.4, flywheel_inertia=0.5, lever_inertia=0.3,
                          lever_mass=8.0, lever_com_distance=0.15, ram_mass=20.0)
MOTOR = dyn.MotorDrive(speed_stiffness=60.0, max_torque=400.0)
MS = 10 ** 6  # ns


def _lagrange():
    """
    Return (Q_theta(q, q', q'', F), p_theta(q, q'), Q_r(q, q', q'', F)) from sympy.

    lagrange_chain's Lagrangian, written from the positions alone (doc/mechanism.md).
    """
    chain = chain_lagrangian(MASS, R1, H_PIVOT, RAM_HEIGHT)
    q, qd, qdd = chain.coordinates, chain.rates, chain.accelerations
    force_on_input, force_on_pin = generalised_forces(chain, (0, 2))
    return (sympy.lambdify((*q, *qd, *qdd, chain.ram_force), force_on_input, 'math'),
            sympy.lambdify((*q, *qd), sympy.diff(chain.lagrangian, qd[0]), 'math'),
            sympy.lambdify((*q, *qd, *qdd, chain.ram_force), force_on_pin, 'math'))


def _radius_of_stroke():
    """Return S -> (r, dr/dS, d2r/dS2), r = S h / sqrt(4 H^2 + S^2) differentiated by sympy."""
    stroke = sympy.Symbol('S', positive=True)
    radius = stroke * H_PIVOT / sympy.sqrt(4 * RAM_HEIGHT ** 2 + stroke ** 2)
    return sympy.lambdify(stroke, (radius, sympy.diff(radius, stroke),
                                   sympy.diff(radius, stroke, 2)), 'math')


def _stepper(loads, stroke=0.2, rate_limit=0.05, offset=0.008, speed=6.0):
    ramp = StrokeRamp(PAPER, 0.08, stroke, rate_limit)
    stepper = MotorStepper(PAPER, MASS, loads, MOTOR, speed, offset, 50.0, 0.005, ramp)
    stepper.integrate_to(0)
    return stepper


def test_motor_acceleration_with_a_moving_crank_radius_from_lagrange():
    """
    theta'' = (T_m - b) / M with r(t), r', r'' against Lagrange's equation (sympy).

    And the stroke screw's force as the node publishes it (tau3 dpsi/dr) against the
    generalised force on r at that motion.
    """
    force_on_input, _, force_on_pin = _lagrange()
    radius_of = _radius_of_stroke()
    loads = dyn.Loads(cutting_force=300.0, ram_friction=20.0, cutting_length=0.05)
    stepper = _stepper(loads)
    stepper.set_stroke_command(0.06)
    checked = 0
    for stamp in range(7 * MS, 2000 * MS, 37 * MS):
        stepper.integrate_to(stamp)
        stroke = stepper.stroke.stroke
        assert 0.06 < stroke < 0.2  # mid-change
        time = stamp / 1e9
        assert stroke == pytest.approx(0.2 - 0.05 * time, rel=1e-12)
        radius, slope, curvature = radius_of(stroke)
        radius_rate, radius_acceleration = -0.05 * slope, 0.0025 * curvature
        assert stepper.stroke.crank_radius == pytest.approx(radius, rel=1e-14)
        assert stepper.stroke.crank_radius_rates() == pytest.approx(
            (radius_rate, radius_acceleration), rel=1e-12)
        arguments = (stepper.input_angle, stepper.offset, radius, stepper.input_speed,
                     0.0, radius_rate)
        at_rest = force_on_input(*arguments, 0.0, 0.0, radius_acceleration,
                                 stepper.ram_load)
        inertia = force_on_input(*arguments, 1.0, 0.0, radius_acceleration,
                                 stepper.ram_load) - at_rest
        expected = (stepper.motor_torque - at_rest) / inertia
        assert stepper.input_acceleration == pytest.approx(expected, rel=1e-9, abs=1e-9)
        # Without r' and r'' it would be another number (the terms are there to see).
        plain = force_on_input(*arguments[:5], 0.0, 0.0, 0.0, 0.0, stepper.ram_load)
        assert abs((stepper.motor_torque - plain) / inertia - expected) > 1e-4
        screw = stepper.efforts().lever_torque * lever_radius_coefficient(
            stepper.geometry, stepper.mechanism_state().flywheel_angle)
        assert screw == pytest.approx(force_on_pin(
            *arguments, stepper.input_acceleration, 0.0, radius_acceleration,
            stepper.ram_load), rel=1e-8, abs=1e-8)
        checked += 1
    assert checked > 40


def _derivative(values, step):
    """Fourth-order central differences at the inner points."""
    return (8.0 * (values[3:-1] - values[1:-3]) - (values[4:] - values[:-4])) / (12.0 * step)


def test_speed_acceleration_and_ram_velocity_are_the_derivatives_while_the_stroke_moves():
    # No load: its switches make the acceleration jump, which differences do not follow.
    stepper = _stepper(dyn.Loads.none())
    stepper.set_stroke_command(0.06)
    step_ns = 10 ** 5  # 0.1 ms
    rows = []
    for stamp in range(300 * MS, 1300 * MS, step_ns):
        sample = stepper.advance_to(stamp)
        rows.append((stepper.input_angle, stepper.input_speed, stepper.input_acceleration,
                     sample.ram_position, sample.ram_velocity, stepper.stroke.crank_radius,
                     stepper.stroke.crank_radius_rates()[0]))
    angle, speed, acceleration, ram, velocity, radius, radius_rate = np.array(rows).T
    assert np.all(radius_rate < 0.0)  # all within the stroke change
    step = 1e-4
    assert np.allclose(_derivative(np.unwrap(angle), step), speed[2:-2], rtol=0, atol=1e-8)
    assert np.allclose(_derivative(speed, step), acceleration[2:-2], rtol=0, atol=1e-6)
    assert np.allclose(_derivative(ram, step), velocity[2:-2], rtol=0, atol=1e-9)
    assert np.allclose(_derivative(radius, step), radius_rate[2:-2], rtol=0, atol=1e-12)


def _energy(stepper, sample):
    kinetic = 0.5 * (MASS.input_inertia * stepper.input_speed ** 2
                     + MASS.flywheel_inertia * sample.flywheel_speed ** 2
                     + MASS.lever_inertia * sample.lever_speed ** 2
                     + MASS.ram_mass * sample.ram_velocity ** 2)
    return kinetic + (MASS.lever_mass * MASS.gravity * MASS.lever_com_distance
                      * math.cos(sample.lever_angle))


def test_energy_balance_over_a_stroke_change():
    """Motor work + screw work + load work = change of T + V, within the stroke change."""
    loads = dyn.Loads(cutting_force=0.0, ram_friction=30.0, cutting_length=0.0)
    stepper = _stepper(loads)
    stepper.set_stroke_command(0.06)
    step_ns = 10 ** 5  # 0.1 ms
    stamps = range(1 * MS, 1601 * MS + step_ns // 2, step_ns)  # the change lasts 2.8 s
    powers = {'motor': [], 'screw': [], 'load': []}
    energies = []
    for stamp in stamps:
        sample = stepper.advance_to(stamp)
        efforts = stepper.efforts()
        screw = efforts.lever_torque * lever_radius_coefficient(stepper.geometry,
                                                                sample.flywheel_angle)
        radius_rate = stepper.stroke.crank_radius_rates()[0]
        assert radius_rate < 0.0
        powers['motor'].append(efforts.input_torque * stepper.input_speed)
        powers['screw'].append(screw * radius_rate)
        powers['load'].append(stepper.ram_load * sample.ram_velocity)
        energies.append(_energy(stepper, sample))
    work = {name: integrate.simpson(np.array(values), dx=step_ns / 1e9)
            for name, values in powers.items()}
    change = energies[-1] - energies[0]
    scale = sum(integrate.simpson(np.abs(values), dx=step_ns / 1e9)
                for values in powers.values())
    assert abs(work['screw']) > 1e-3 * scale  # the screw's share is there to see
    # Simpson's rule over the friction's kinks (its power is -F |v|) is good to about 1e-6.
    assert abs(work['motor'] + work['screw'] + work['load'] - change) < 2e-6 * scale


def test_the_input_momentum_is_kept_when_the_screw_starts_and_stops():
    """The speed jumps where r' does, p_theta = dT/d(theta') kept (sympy's T)."""
    _, momentum, _ = _lagrange()
    radius_of = _radius_of_stroke()
    stepper = _stepper(dyn.Loads.none(), stroke=0.1, rate_limit=0.2)
    stepper.integrate_to(10 * MS)
    before = (stepper.input_angle, stepper.offset, stepper.stroke.crank_radius,
              stepper.input_speed)
    stepper.set_stroke_command(0.16)
    stepper.integrate_to(10 * MS + 1)
    # The same instant within 1 ns: the speed jumped, the momentum did not.
    radius_rate = 0.2 * radius_of(stepper.stroke.stroke)[1]
    assert stepper.input_speed != pytest.approx(before[3], abs=1e-6)
    assert momentum(*before[:3], before[3], 0.0, 0.0) == pytest.approx(
        momentum(stepper.input_angle, stepper.offset, stepper.stroke.crank_radius,
                 stepper.input_speed, 0.0, radius_rate), rel=1e-7)
    # At the end (0.3 s later) the screw stops: the speed jumps back by the same rule.
    end = 10 * MS + 300 * MS
    stepper.integrate_to(end - 1)
    moving = (stepper.input_angle, stepper.offset, stepper.stroke.crank_radius,
              stepper.input_speed, 0.0, stepper.stroke.crank_radius_rates()[0])
    stepper.integrate_to(end + 1)
    assert stepper.stroke.stroke == 0.16 and stepper.stroke.rate == 0.0
    assert momentum(*moving) == pytest.approx(
        momentum(stepper.input_angle, stepper.offset, stepper.stroke.crank_radius,
                 stepper.input_speed, 0.0, 0.0), rel=1e-7)


def test_motor_stepper_moves_the_stroke_at_its_limit_and_ends_on_the_lean_forms():
    stepper = _stepper(dyn.Loads.small_shaper(), stroke=0.2, rate_limit=0.1)
    stepper.set_stroke_command(0.16)
    stepper.integrate_to(200 * MS)
    assert stepper.stroke.stroke == pytest.approx(0.18, rel=1e-12)
    assert stepper.geometry.crank_radius == pytest.approx(
        crank_radius_for_stroke(stepper.stroke.stroke, H_PIVOT, RAM_HEIGHT), rel=1e-15)
    stepper.integrate_to(1000 * MS)
    assert stepper.stroke.stroke == 0.16 and stepper.stroke.rate == 0.0
    # Arrived: the segment's equation is the new radius's (its lean forms).
    assert stepper.segment.equation.geometry is stepper.geometry
    assert all(map(math.isfinite, stepper.efforts()))
    # The same commands at the same stamps, other stamps asked: the same state.
    other = _stepper(dyn.Loads.small_shaper(), stroke=0.2, rate_limit=0.1)
    other.set_stroke_command(0.16)
    for stamp in range(1 * MS, 1000 * MS + 1, 7 * MS + 13):
        other.integrate_to(stamp)
    other.integrate_to(1000 * MS)
    assert other.input_angle == pytest.approx(stepper.input_angle, abs=1e-9)
    assert other.input_speed == pytest.approx(stepper.input_speed, abs=1e-9)


def test_the_screw_moves_the_pin_of_a_stalled_shaft():
    """The stroke moves at its rate whether the shaft turns or not (the operator's screw)."""
    heavy = dyn.Loads(cutting_force=20000.0, ram_friction=20.0, cutting_length=0.05)
    stepper = _stepper(heavy, rate_limit=0.05, offset=0.0)
    for stamp in range(MS, 3000 * MS, 10 * MS):
        stepper.integrate_to(stamp)
    assert stepper.stalled and stepper.input_speed == 0.0
    stepper.set_stroke_command(0.1)
    # The screw's start is an impulse on the pin: the input's momentum is kept, so the
    # shaft gets a kick (test_the_input_momentum_is_kept...) and the stall rule takes over.
    for stamp in range(3000 * MS, 4000 * MS, 10 * MS):
        sample = stepper.advance_to(stamp)
        assert all(map(math.isfinite, (*sample, *stepper.efforts())))
    assert stepper.stroke.stroke == pytest.approx(0.2 - 0.05 * 0.999, rel=1e-12)  # 2.991 s on
    stepper.integrate_to(6000 * MS)
    assert stepper.stroke.stroke == 0.1 and stepper.stroke.rate == 0.0
    assert stepper.stalled  # the cut is still too much for the motor


def test_a_clock_jump_mid_change_holds_the_stroke_reached_with_the_state():
    stepper = _stepper(dyn.Loads.small_shaper(), rate_limit=1e-4)  # 1400 s to arrive
    with pytest.raises(dyn.DynamicsError, match='cutting_length = 0.15 m is out of range: '
                                                'allowed 0 to the ram stroke, 0.06 m'):
        stepper.set_stroke_command(0.06)  # shorter than the workpiece
    stepper.set_dynamics(loads=dyn.Loads(cutting_force=400.0, ram_friction=20.0,
                                         cutting_length=0.05))
    stepper.set_stroke_command(0.06)
    stepper.integrate_to(500 * MS)
    stepper.integrate_to(10 ** 6 * MS)  # 1000 s ahead: past the bounded effort
    assert stepper.integration_cutoffs == 1
    reached = stepper.stroke.stroke
    assert 0.06 < reached < 0.2 - 1e-4 * 0.5  # held where the state was reached
    assert stepper.geometry.crank_radius == pytest.approx(
        crank_radius_for_stroke(reached, H_PIVOT, RAM_HEIGHT), rel=1e-15)
    stepper.integrate_to(10 ** 6 * MS + 100 * MS)  # and moves on from there
    assert stepper.stroke.stroke == pytest.approx(reached - 1e-5, rel=1e-9)


def test_the_lean_moving_radius_form_is_the_chain():
    """moving_radius_motion_of against dynamics.evaluate_chain with r' and r''."""
    constants = lean_constants(PAPER, MASS)
    rng = np.random.default_rng(7)
    for _ in range(200):
        offset, angle, speed = rng.uniform(-0.02, 0.02), rng.uniform(-4, 4), rng.uniform(-9, 9)
        offset_rate, torque, load = rng.uniform(-0.01, 0.01), rng.uniform(-300, 300), \
            rng.uniform(-500, 500)
        radius, radius_rate, radius_acceleration = rng.uniform(0.01, 0.08), \
            rng.uniform(-0.02, 0.02), rng.uniform(-0.1, 0.1)
        chain = dyn.evaluate_chain(dyn.SCALAR_OPS, R1, radius, H_PIVOT, RAM_HEIGHT, 0.0,
                                   MASS.scalars(), offset, angle, speed, 0.0, offset_rate, 0.0,
                                   load, radius_rate, radius_acceleration)
        acceleration, position, velocity = moving_radius_motion_of(
            constants, offset, angle, speed, offset_rate, torque, load, radius, radius_rate,
            radius_acceleration)
        expected = (torque - chain.efforts.input_torque) / chain.generalized_inertia
        assert acceleration == pytest.approx(expected, rel=1e-12, abs=1e-12)
        assert (position, velocity) == pytest.approx(
            (chain.ram_position, chain.ram_velocity), rel=1e-13, abs=1e-15)
