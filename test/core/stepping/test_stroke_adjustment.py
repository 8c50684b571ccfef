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
The stroke adjustment: stroke and crank radius, a moving crank pin's kinematics and efforts.

Independent routes: the stroke against the ram's extreme positions sampled densely; the
crank radius' rates, the joints' velocities and accelerations against finite differences of
positions; the efforts against Lagrange's equations derived symbolically (sympy) from the
energies of doc/dynamics.md, and against the power balance.
"""

import math

import numpy as np
import pytest
from scipy import integrate
import sympy

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import (crank_radius_for_stroke, Geometry, KinematicsError,
                                              stroke_for_crank_radius)
from qrm_ros.core.kinematics.mechanism_state import state
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.stepping.stepping import ShaperStepper
from qrm_ros.core.stepping.stroke_adjustment import (check_stroke, crank_radius_motion,
                                                     largest_stroke, StrokeRamp)
from qrm_ros.core.dynamics.stroke_efforts import (efforts_with_stroke_screw,
                                                  lever_radius_coefficient)

from lagrange_chain import chain_lagrangian, generalised_forces

PAPER = Geometry.paper()
MASS = dyn.MassProperties(input_inertia=0.01, flywheel_inertia=0.5, lever_inertia=0.3,
                          lever_mass=8.0, lever_com_distance=0.15, ram_mass=20.0)


def _derivative(function, x, step):
    """Fourth-order central difference."""
    return (8.0 * (function(x + step) - function(x - step))
            - (function(x + 2 * step) - function(x - 2 * step))) / (12.0 * step)


def _second_derivative(function, x, step):
    """Fourth-order central second difference."""
    return (-function(x + 2 * step) + 16.0 * function(x + step) - 30.0 * function(x)
            + 16.0 * function(x - step) - function(x - 2 * step)) / (12.0 * step * step)


@pytest.mark.parametrize('radius', [0.01, 0.0303, 0.0505, 0.09])
def test_stroke_is_the_span_of_the_ram_and_the_radius_its_inverse(radius):
    geometry = Geometry(0.025, radius, 0.113, 0.2)
    positions = state(geometry, 0.0, np.linspace(-np.pi, np.pi, 400001), 1.0).ram_position
    stroke = stroke_for_crank_radius(radius, 0.113, 0.2)
    assert positions.max() - positions.min() == pytest.approx(stroke, rel=1e-9)
    assert float(geometry.ram_stroke) == stroke
    assert crank_radius_for_stroke(stroke, 0.113, 0.2) == pytest.approx(radius, rel=1e-14)


def test_paper_short_stroke_radius():
    """60 mm of stroke on the paper's lever: r = S h / sqrt(4 H^2 + S^2)."""
    radius = crank_radius_for_stroke(0.06, 0.113, 0.2)
    assert radius == pytest.approx(0.06 * 0.113 / math.sqrt(0.16 + 0.0036), rel=1e-15)
    assert stroke_for_crank_radius(radius, 0.113, 0.2) == pytest.approx(0.06, rel=1e-14)


@pytest.mark.parametrize('stroke, rate', [(0.06, 0.01), (0.2, -0.03), (0.35, 0.2)])
def test_crank_radius_rates_against_finite_differences(stroke, rate):
    def radius_at(t):
        return crank_radius_for_stroke(stroke + rate * t, 0.113, 0.2)
    radius, radius_rate, radius_acceleration = crank_radius_motion(stroke, rate, 0.113, 0.2)
    assert radius == pytest.approx(radius_at(0.0), rel=1e-15)
    assert radius_rate == pytest.approx(_derivative(radius_at, 0.0, 1e-3), rel=1e-9)
    assert radius_acceleration == pytest.approx(_second_derivative(radius_at, 0.0, 1e-2),
                                                rel=1e-6)


class MovingPin:
    """A smooth prescribed motion: input, a linearly moving offset, a wobbling crank radius."""

    def input(self, t):
        return (0.3 + 5.0 * t + 1.5 * t * t + 0.05 * np.sin(4.0 * t),
                5.0 + 3.0 * t + 0.2 * np.cos(4.0 * t), 3.0 - 0.8 * np.sin(4.0 * t))

    def offset(self, t):
        return -0.004 + 0.006 * t, 0.006, 0.0

    def radius(self, t):
        return (0.04 + 0.012 * np.sin(2.1 * t), 0.0252 * np.cos(2.1 * t),
                -0.05292 * np.sin(2.1 * t))


def _state_of(path, t, with_rates=True):
    angle, speed, acceleration = path.input(t)
    offset, offset_rate, _ = path.offset(t)
    radius, radius_rate, radius_acceleration = path.radius(t)
    geometry = Geometry(0.025, radius, 0.113, 0.2)
    if not with_rates:
        return state(geometry, offset, angle, 0.0)
    return state(geometry, offset, angle, speed, acceleration, offset_rate, radius_rate,
                 radius_acceleration)


@pytest.mark.parametrize('t', np.linspace(0.1, 1.9, 7))
def test_moving_crank_radius_velocities_and_accelerations_are_the_derivatives(t):
    path = MovingPin()
    exact = _state_of(path, t)
    for position, rate, acceleration in (('flywheel_angle', 'flywheel_speed', None),
                                         ('lever_angle', 'lever_speed', None),
                                         ('ram_position', 'ram_velocity',
                                          'ram_acceleration')):
        def at(time, name=position):
            return getattr(_state_of(path, time, False), name)
        assert getattr(exact, rate) == pytest.approx(_derivative(at, t, 1e-4), rel=1e-8,
                                                     abs=1e-10)
        if acceleration:
            assert getattr(exact, acceleration) == pytest.approx(
                _second_derivative(at, t, 1e-3), rel=1e-6, abs=1e-8)

    def lever_speed(time):
        return _state_of(path, time).lever_speed
    # The lever's acceleration (the chain's) is the derivative of its speed.
    chain = dyn.evaluate_chain(dyn.ARRAY_OPS, 0.025, path.radius(t)[0], 0.113, 0.2, 0.0,
                               MASS.as_dict(), path.offset(t)[0], *path.input(t),
                               path.offset(t)[1], 0.0, 0.0, *path.radius(t)[1:])
    assert chain.lever_acceleration == pytest.approx(_derivative(lever_speed, t, 1e-4),
                                                     rel=1e-7)
    assert chain.lever_speed == pytest.approx(exact.lever_speed, rel=1e-13)
    assert chain.ram_acceleration == pytest.approx(exact.ram_acceleration, rel=1e-11)


def _lagrange_generalised_forces():
    """
    Q = d/dt dL/dq' - dL/dq - F_ext dx/dq for q = (theta, offset, r), derived with sympy.

    lagrange_chain's Lagrangian (doc/mechanism.md's positions alone). Returns a numeric
    function of (q, q', q'', F_ext) giving the three forces.
    """
    chain = chain_lagrangian(MASS, 0.025, 0.113, 0.2)
    return sympy.lambdify((*chain.coordinates, *chain.rates, *chain.accelerations,
                           chain.ram_force), generalised_forces(chain), 'math')


def test_efforts_with_moving_crank_radius_from_a_symbolic_lagrange_derivation():
    """tau1, F_offset and the stroke screw's F_r against Lagrange's equations (sympy)."""
    forces_of = _lagrange_generalised_forces()
    rng = np.random.default_rng(25)
    for _ in range(12):
        angle, speed, acceleration = rng.uniform(-np.pi, np.pi), rng.uniform(-9, 9), \
            rng.uniform(-30, 30)
        offset, offset_rate, offset_acceleration = rng.uniform(-0.02, 0.02), \
            rng.uniform(-0.01, 0.01), rng.uniform(-0.05, 0.05)
        radius, radius_rate, radius_acceleration = rng.uniform(0.01, 0.09), \
            rng.uniform(-0.02, 0.02), rng.uniform(-0.1, 0.1)
        force = rng.uniform(-500, 500)
        torque, offset_force, radius_force = forces_of(
            angle, offset, radius, speed, offset_rate, radius_rate, acceleration,
            offset_acceleration, radius_acceleration, force)
        geometry = Geometry(0.025, radius, 0.113, 0.2)
        efforts, screw = efforts_with_stroke_screw(
            geometry, MASS, offset, angle, speed, acceleration, offset_rate,
            offset_acceleration, force, radius_rate, radius_acceleration)
        assert efforts.input_torque == pytest.approx(torque, rel=1e-9, abs=1e-9)
        assert efforts.offset_force == pytest.approx(offset_force, rel=1e-9, abs=1e-7)
        assert screw == pytest.approx(radius_force, rel=1e-9, abs=1e-7)


def test_still_crank_radius_leaves_the_efforts_as_they_were():
    """Zero rates: the same numbers as dynamics.efforts, and F_r = tau3 d(psi)/d(r)."""
    for angle in np.linspace(-3.0, 3.0, 7):
        plain = dyn.efforts(PAPER, MASS, 0.01, angle, 6.0, 2.0, 0.003, 0.0, 150.0)
        efforts, screw = efforts_with_stroke_screw(PAPER, MASS, 0.01, angle, 6.0, 2.0, 0.003,
                                                   0.0, 150.0)
        assert tuple(efforts) == tuple(plain)
        flywheel_angle = state(PAPER, 0.01, angle, 6.0).flywheel_angle
        assert screw == pytest.approx(
            plain.lever_torque * lever_radius_coefficient(PAPER, flywheel_angle), rel=1e-12)


def test_power_balance_with_a_moving_crank_radius():
    """Work of the input, the offset actuator, the stroke screw and F_ext = change of T + V."""
    path = MovingPin()

    def chain_at(t):
        radius, radius_rate, radius_acceleration = path.radius(t)
        geometry = Geometry(0.025, radius, 0.113, 0.2)
        offset, offset_rate, offset_acceleration = path.offset(t)
        return efforts_with_stroke_screw(geometry, MASS, offset, *path.input(t), offset_rate,
                                         offset_acceleration, 200.0 * math.sin(3.0 * t),
                                         radius_rate, radius_acceleration)

    def power(t):
        efforts, screw = chain_at(t)
        s = _state_of(path, t)
        return (efforts.input_torque * path.input(t)[1] + efforts.offset_force
                * path.offset(t)[1] + screw * path.radius(t)[1]
                + 200.0 * math.sin(3.0 * t) * s.ram_velocity)

    def total_energy(t):
        s = _state_of(path, t)
        kinetic = 0.5 * (MASS.input_inertia * path.input(t)[1] ** 2 + MASS.flywheel_inertia
                         * s.flywheel_speed ** 2 + MASS.lever_inertia * s.lever_speed ** 2
                         + MASS.ram_mass * s.ram_velocity ** 2)
        return kinetic + (MASS.lever_mass * MASS.gravity * MASS.lever_com_distance
                          * math.cos(s.lever_angle))

    for start, end in ((0.0, 0.6), (0.4, 1.9)):
        work = integrate.quad(power, start, end, epsabs=0.0, epsrel=1e-12, limit=500)[0]
        scale = integrate.quad(lambda t: abs(power(t)), start, end, limit=500)[0]
        assert abs(work - (total_energy(end) - total_energy(start))) <= 1e-10 * scale


def test_stroke_ramp_moves_at_its_limit_and_refuses_with_the_range():
    ramp = StrokeRamp(PAPER, 0.08, 0.2, 0.01)
    ramp.set_command(0.06)
    assert ramp.rate == -0.01
    ramp.advance(2.0)
    assert ramp.stroke == pytest.approx(0.18, rel=1e-15)
    assert ramp.crank_radius == pytest.approx(crank_radius_for_stroke(0.18, 0.113, 0.2))
    radius_rate, radius_acceleration = ramp.crank_radius_rates()
    assert (radius_rate, radius_acceleration) == crank_radius_motion(ramp.stroke, -0.01,
                                                                     0.113, 0.2)[1:]
    ramp.advance(100.0)
    assert (ramp.stroke, ramp.rate, ramp.crank_radius_rates()) == (0.06, 0.0, (0.0, 0.0))
    limit = largest_stroke(PAPER, 0.08)
    with pytest.raises(KinematicsError, match=r'stroke_length 0\.5 m is out of range: '
                                              r"allowed 0 < stroke_length <= 0\.400972 m"):
        ramp.set_command(0.5)
    for bad in (0.0, -0.1, math.nan, limit * 1.000001):
        with pytest.raises(KinematicsError, match='stroke_length'):
            check_stroke(PAPER, bad, 0.08)
    assert check_stroke(PAPER, limit, 0.08) == limit
    with pytest.raises(KinematicsError, match='max_crank_radius 0.113 m is out of range'):
        StrokeRamp(PAPER, 0.113, 0.2, 0.01)
    ramp.reset(0.2)
    assert (ramp.stroke, ramp.command) == (0.2, 0.2)


def test_speed_drive_stepper_moves_the_stroke_with_continuous_exact_states():
    """A stroke change under ShaperStepper: velocities are the derivative of positions."""
    stepper = ShaperStepper(PAPER, 6.0, 0.01, 20.0, 0.005, StrokeRamp(PAPER, 0.08, 0.2, 0.02))
    stepper.integrate_to(0)
    stepper.set_stroke_command(0.06)
    step = 10 ** 5  # 0.1 ms
    stamps = np.arange(0, 3 * 10 ** 9, step)
    samples = [stepper.advance_to(int(stamp)) for stamp in stamps[:20000]]
    ram = np.array([sample.ram_position for sample in samples])
    velocity = np.array([sample.ram_velocity for sample in samples])
    lever = np.array([sample.lever_angle for sample in samples])
    lever_speed = np.array([sample.lever_speed for sample in samples])
    # Forward differences over 0.1 ms against the rates from each stamp on (first order).
    assert np.max(np.abs(np.diff(ram) / 1e-4 - 0.5 * (velocity[1:] + velocity[:-1]))) < 2e-4
    assert np.max(np.abs(np.diff(lever) / 1e-4 - 0.5 * (lever_speed[1:] + lever_speed[:-1]))) \
        < 2e-3
    assert stepper.stroke.stroke == pytest.approx(0.2 - 0.02 * 1.9999, rel=1e-9)
    assert stepper.geometry.crank_radius == pytest.approx(
        crank_radius_for_stroke(stepper.stroke.stroke, 0.113, 0.2), rel=1e-15)
    stepper.integrate_to(10 * 10 ** 9)
    assert stepper.stroke.stroke == 0.06 and stepper.stroke.rate == 0.0
    stepper.reset(6.0, 0.0, stroke_length=float(PAPER.ram_stroke))
    assert stepper.geometry is PAPER  # the base's own stroke: its own radius, exactly


def test_motor_stepper_takes_the_stroke_and_refuses_one_the_slot_cannot_hold():
    """The motor drive moves the stroke too (test_motor_stroke); refusals as the ramp's."""
    short = StrokeRamp(PAPER, 0.08, 0.1, 0.01)
    stepper = MotorStepper(PAPER, MASS, dyn.Loads.none(), dyn.MotorDrive.small_shaper(), 6.0,
                           0.0, 20.0, 0.005, short)
    assert stepper.geometry is short.geometry
    assert stepper.geometry.crank_radius == pytest.approx(crank_radius_for_stroke(0.1, 0.113,
                                                                                  0.2))
    with pytest.raises(KinematicsError, match=r'stroke_length 0\.5 m is out of range: '
                                              r'allowed 0 < stroke_length <= 0\.400972 m'):
        stepper.set_stroke_command(0.5)
    assert short.command == 0.1  # a refused command changes nothing
    stepper.integrate_to(0)
    stepper.set_stroke_command(0.06)
    stepper.integrate_to(10 ** 9)
    assert short.stroke == pytest.approx(0.09, rel=1e-12) and short.rate == -0.01
    stepper.reset(6.0, 0.0, stroke_length=0.1)
    assert (short.stroke, short.command, short.rate) == (0.1, 0.1, 0.0)
    # A stroke already moving (a drive switched mid-change) goes on moving.
    moving = StrokeRamp(PAPER, 0.08, 0.1, 0.01)
    moving.set_command(0.06)
    stepper = MotorStepper(PAPER, MASS, dyn.Loads.none(), None, 6.0, 0.0, 20.0, 0.005, moving)
    stepper.integrate_to(0)
    stepper.integrate_to(10 ** 9)
    assert moving.stroke == pytest.approx(0.09, rel=1e-12)
