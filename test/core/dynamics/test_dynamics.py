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
Efforts and generalised inertia against the design note and two independent derivations.

The independent routes never use the dynamics module's velocity coefficients: energies come
from the kinematics core's velocities (its own pin-vector formulas), and Lagrange's equations
are formed by finite differences of a Lagrangian built from those.
"""

import math

import numpy as np
import pytest
from scipy import integrate

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import state

CHECK_GEOMETRY = Geometry(0.025, 0.0505, 0.113, 0.2)
CHECK_MASS = dyn.MassProperties(input_inertia=0.01, flywheel_inertia=0.5, lever_inertia=0.3,
                                lever_mass=8.0, lever_com_distance=0.15, ram_mass=20.0,
                                gravity=9.81)

# dynamics.md's check table: angle, speed, acceleration, offset, offset rate, F_ext,
# input torque, offset force, generalised inertia.
CHECK_TABLE = [
    (1.0, 2 * math.pi, 0.0, 0.01, 0.0, 0.0, -0.517749286829, -8.37179597869, 0.330327333115),
    (1.0, 2 * math.pi, 0.0, 0.01, 0.0, 500.0, 21.8419241975, 353.175055602, 0.330327333115),
    (2.5, 2 * math.pi, 3.0, -0.01, 0.004, 0.0, -15.259935119, 644.18903277, 0.713528369261),
    (4.0, -5.0, 0.0, 0.015, 0.0, 0.0, 16.2542735589, -778.46800713, 0.760494971453),
]


@pytest.mark.parametrize('row', CHECK_TABLE)
def test_design_note_check_table(row):
    angle, speed, acceleration, offset, rate, force, torque, offset_force, inertia = row
    result = dyn.efforts(CHECK_GEOMETRY, CHECK_MASS, offset, angle, speed, acceleration, rate,
                         external_ram_force=force)
    # The table's 12 significant digits.
    assert result.input_torque == pytest.approx(torque, rel=1e-11)
    assert result.offset_force == pytest.approx(offset_force, rel=1e-11)
    assert dyn.generalized_inertia(CHECK_GEOMETRY, CHECK_MASS, offset, angle) == \
        pytest.approx(inertia, rel=1e-11)


def energy(geometry, mass, offset, angle, speed, offset_rate=0.0):
    """T + V from the kinematics core's velocities (dynamics.md's energies)."""
    s = state(geometry, offset, angle, speed, 0.0, offset_rate)
    kinetic = 0.5 * (mass.input_inertia * speed ** 2 + mass.flywheel_inertia
                     * s.flywheel_speed ** 2 + mass.lever_inertia * s.lever_speed ** 2
                     + mass.ram_mass * s.ram_velocity ** 2)
    potential = mass.lever_mass * mass.gravity * mass.lever_com_distance * np.cos(s.lever_angle)
    return kinetic + potential


class Trajectory:
    """A smooth prescribed motion: ramping, wobbling input speed and an oscillating offset."""

    def __init__(self, mean_offset=0.005, offset_swing=0.012, speed=6.0, ramp=4.0):
        self.mean_offset, self.offset_swing = mean_offset, offset_swing
        self.speed, self.ramp = speed, ramp

    def input(self, t):
        """Angle, speed, acceleration."""
        wobble = np.sin(3.0 * t)
        return (0.4 + self.speed * t + 0.5 * self.ramp * t * t + 0.03 * wobble,
                self.speed + self.ramp * t + 0.09 * np.cos(3.0 * t), self.ramp - 0.27 * wobble)

    def offset(self, t):
        """Offset, rate, acceleration."""
        return (self.mean_offset + self.offset_swing * np.sin(1.7 * t),
                1.7 * self.offset_swing * np.cos(1.7 * t),
                -1.7 ** 2 * self.offset_swing * np.sin(1.7 * t))


def external_force(t):
    return 300.0 + 200.0 * np.sin(2.3 * t)


def test_energy_balance_with_ramping_speed_and_moving_offset():
    """Work of the input, the offset actuator and F_ext equals the change of T + V."""
    geometry, mass, path = Geometry.paper(), dyn.MassProperties.small_shaper(), Trajectory()

    def power(t):
        angle, speed, acceleration = path.input(t)
        offset, rate, offset_acceleration = path.offset(t)
        result = dyn.efforts(geometry, mass, offset, angle, speed, acceleration, rate,
                             offset_acceleration, external_force(t))
        ram_velocity = state(geometry, offset, angle, speed, acceleration, rate).ram_velocity
        return (result.input_torque * speed + result.offset_force * rate
                + external_force(t) * ram_velocity)

    def total_energy(t):
        return energy(geometry, mass, path.offset(t)[0], path.input(t)[0], path.input(t)[1],
                      path.offset(t)[1])

    for start, end in ((0.0, 0.5), (0.5, 1.3), (0.0, 2.0)):
        work, error = integrate.quad(power, start, end, epsabs=0.0, epsrel=1e-12, limit=500)
        change = total_energy(end) - total_energy(start)
        scale = integrate.quad(lambda t: abs(power(t)), start, end, limit=500)[0]
        assert abs(work - change) <= 1e-10 * scale, (start, end, work, change)


def _derivative(function, x, step):
    """Fourth-order central difference."""
    return (8.0 * (function(x + step) - function(x - step))
            - (function(x + 2 * step) - function(x - 2 * step))) / (12.0 * step)


def test_input_torque_and_offset_force_from_lagrange_equations():
    """tau1 and F_offset from d/dt dL/dq' - dL/dq = Q, L from the kinematics core."""
    geometry, mass, path = Geometry.paper(), dyn.MassProperties.small_shaper(), Trajectory()

    def lagrangian(angle, speed, offset, rate):
        s = state(geometry, offset, angle, speed, 0.0, rate)
        kinetic = 0.5 * (mass.input_inertia * speed ** 2 + mass.flywheel_inertia
                         * s.flywheel_speed ** 2 + mass.lever_inertia * s.lever_speed ** 2
                         + mass.ram_mass * s.ram_velocity ** 2)
        return kinetic - (mass.lever_mass * mass.gravity * mass.lever_com_distance
                          * np.cos(s.lever_angle))

    def ram_position(angle, offset):
        return state(geometry, offset, angle, 0.0).ram_position

    for t in np.linspace(0.05, 1.95, 9):
        angle, speed, acceleration = path.input(t)
        offset, rate, offset_acceleration = path.offset(t)
        force = external_force(t)

        def momentum_input(time):
            a, w, _ = path.input(time)
            d, v, _ = path.offset(time)
            return _derivative(lambda x: lagrangian(a, x, d, v), w, 1e-3)

        def momentum_offset(time):
            a, w, _ = path.input(time)
            d, v, _ = path.offset(time)
            return _derivative(lambda x: lagrangian(a, w, d, x), v, 1e-5)

        torque = (_derivative(momentum_input, t, 1e-4)
                  - _derivative(lambda x: lagrangian(x, speed, offset, rate), angle, 1e-4)
                  - force * _derivative(lambda x: ram_position(x, offset), angle, 1e-4))
        offset_force = (_derivative(momentum_offset, t, 1e-4)
                        - _derivative(lambda x: lagrangian(angle, speed, x, rate), offset, 1e-6)
                        - force * _derivative(lambda x: ram_position(angle, x), offset, 1e-6))
        result = dyn.efforts(geometry, mass, offset, angle, speed, acceleration, rate,
                             offset_acceleration, force)
        assert result.input_torque == pytest.approx(torque, rel=1e-7, abs=1e-6)
        assert result.offset_force == pytest.approx(offset_force, rel=1e-7, abs=1e-4)


def test_downstream_efforts_from_lagrange_equations_of_each_sub_chain():
    """Flywheel torque, lever torque and ram force: Lagrange on the bodies after each joint."""
    geometry, mass = Geometry.paper(), dyn.MassProperties.small_shaper()
    gravity_moment = mass.lever_mass * mass.gravity * mass.lever_com_distance
    rng = np.random.default_rng(9)
    for _ in range(6):
        phi, phi_speed, phi_acc = rng.uniform(-np.pi, np.pi), rng.uniform(-20, 20), \
            rng.uniform(-50, 50)
        force = rng.uniform(-500, 500)
        # With no offset the coupling is an identity: input angle = flywheel angle.
        angle_of = state(geometry, 0.0, phi, phi_speed, phi_acc)

        def lever_angle(x):
            return state(geometry, 0.0, x, 0.0).lever_angle

        def ram_of_lever(psi):
            return geometry.ram_height * math.tan(psi)

        psi, psi_speed = angle_of.lever_angle, angle_of.lever_speed
        dpsi = _derivative(lever_angle, phi, 1e-4)
        d2psi = (lever_angle(phi + 1e-4) - 2 * lever_angle(phi) + lever_angle(phi - 1e-4)) / 1e-8
        psi_acc = dpsi * phi_acc + d2psi * phi_speed ** 2
        dx = _derivative(ram_of_lever, psi, 1e-5)
        d2x = (ram_of_lever(psi + 1e-4) - 2 * ram_of_lever(psi) + ram_of_lever(psi - 1e-4)) / 1e-8
        x_acc = dx * psi_acc + d2x * psi_speed ** 2
        ram_force = mass.ram_mass * x_acc - force
        lever_torque = (mass.lever_inertia * psi_acc - gravity_moment * math.sin(psi)
                        + ram_force * dx)
        flywheel_torque = mass.flywheel_inertia * phi_acc + lever_torque * dpsi
        result = dyn.efforts(geometry, mass, 0.0, phi, phi_speed, phi_acc,
                             external_ram_force=force)
        assert result.ram_force == pytest.approx(ram_force, rel=1e-5, abs=1e-3)
        assert result.lever_torque == pytest.approx(lever_torque, rel=1e-5, abs=1e-4)
        assert result.flywheel_torque == pytest.approx(flywheel_torque, rel=1e-5, abs=1e-4)
        # No offset: d(phi)/d(theta) = 1, so the input adds only its own inertia torque.
        assert result.input_torque == pytest.approx(
            result.flywheel_torque + mass.input_inertia * phi_acc, rel=1e-13, abs=1e-12)


def test_generalized_inertia_is_twice_kinetic_energy_per_speed_squared():
    geometry, mass = Geometry.paper(), dyn.MassProperties.small_shaper()
    angles = np.linspace(-np.pi, np.pi, 37)
    for offset in (-0.02, 0.0, 0.015):
        kinetic = energy(geometry, dyn.MassProperties(
            mass.input_inertia, mass.flywheel_inertia, mass.lever_inertia, 0.0, 0.0,
            mass.ram_mass), offset, angles, 3.0)
        assert np.allclose(dyn.generalized_inertia(geometry, mass, offset, angles),
                           2.0 * kinetic / 9.0, rtol=1e-13, atol=0.0)


def test_efforts_are_affine_in_acceleration_with_slope_the_generalized_inertia():
    geometry, mass = Geometry.paper(), dyn.MassProperties.small_shaper()
    angles = np.linspace(0.0, 2 * np.pi, 25)
    at_zero = dyn.efforts(geometry, mass, 0.01, angles, 5.0, 0.0, 0.002)
    at_ten = dyn.efforts(geometry, mass, 0.01, angles, 5.0, 10.0, 0.002)
    slope = (at_ten.input_torque - at_zero.input_torque) / 10.0
    assert np.allclose(slope, dyn.generalized_inertia(geometry, mass, 0.01, angles),
                       rtol=1e-9)


def test_ram_acceleration_agrees_with_the_kinematics_core():
    geometry = Geometry.paper()
    rng = np.random.default_rng(4)
    angles, speeds = rng.uniform(-4, 4, 200), rng.uniform(-30, 30, 200)
    accelerations, offsets = rng.uniform(-80, 80, 200), rng.uniform(-0.02, 0.02, 200)
    rates = rng.uniform(-0.01, 0.01, 200)
    chain = dyn.array_chain(geometry, dyn.MassProperties.small_shaper(), offsets, angles,
                            speeds, accelerations, rates)
    reference = state(geometry, offsets, angles, speeds, accelerations, rates)
    scale = np.abs(reference.ram_acceleration).max()
    assert np.abs(chain.ram_acceleration - reference.ram_acceleration).max() <= 1e-12 * scale
    assert np.allclose(chain.ram_velocity, reference.ram_velocity, rtol=1e-12, atol=1e-15)
    assert np.allclose(chain.lever_angle, reference.lever_angle, rtol=0, atol=1e-15)


def test_efforts_broadcast_and_return_floats_for_scalars():
    geometry, mass = Geometry.paper(), dyn.MassProperties.small_shaper()
    one = dyn.efforts(geometry, mass, 0.0, 1.0, 2.0)
    assert all(type(value) is float for value in one)
    many = dyn.efforts(geometry, mass, np.array([[0.0], [0.01]]), np.linspace(0, 1, 4), 2.0)
    assert all(np.shape(value) == (2, 4) for value in many)
    assert many.input_torque[0, 3] == pytest.approx(one.input_torque, rel=1e-15)


def test_ram_load_force():
    loads = dyn.Loads(cutting_force=400.0, ram_friction=20.0, cutting_length=0.1)
    x = np.array([0.0, 0.05, 0.0501, -0.05, 0.0, 0.0, 0.09])
    v = np.array([-1.0, -1.0, -1.0, -0.2, 1.0, 0.0, -0.3])
    assert list(dyn.ram_load_force(loads, x, v, 0.2)) == [420.0, 420.0, 20.0, 420.0, -20.0,
                                                          0.0, 20.0]
    with pytest.raises(dyn.DynamicsError, match=r'cutting_length = 0.1 m is out of range: '
                       r'allowed 0 to the ram stroke, 0.05 m'):
        dyn.ram_load_force(loads, 0.0, 0.0, 0.05)


@pytest.mark.parametrize('kind, field, value, message', [
    (dyn.MassProperties, 'ram_mass', -1.0, r'ram_mass = -1.0 kg is out of range: allowed >= 0'),
    (dyn.MassProperties, 'gravity', float('nan'), r'gravity must be finite \(m/s\^2\)'),
    (dyn.MassProperties, 'lever_inertia', 'heavy', r'lever_inertia must be a real number'),
    (dyn.Loads, 'cutting_force', -5.0, r'cutting_force = -5.0 N is out of range'),
    (dyn.Loads, 'cutting_length', float('inf'), r'cutting_length must be finite'),
    (dyn.MotorDrive, 'speed_stiffness', 0.0,
     r'speed_stiffness = 0.0 N\*m\*s/rad is out of range: allowed > 0'),
    (dyn.MotorDrive, 'max_torque', True, r'max_torque must be a real number in N\*m'),
])
def test_bad_parameters_are_refused_naming_field_value_and_range(kind, field, value, message):
    values = kind.small_shaper().as_dict()
    values[field] = value
    with pytest.raises(dyn.DynamicsError, match=message):
        kind(**values)


def test_zero_input_and_flywheel_inertia_refused():
    values = dyn.MassProperties.small_shaper().as_dict()
    values.update(input_inertia=0.0, flywheel_inertia=0.0)
    with pytest.raises(dyn.DynamicsError, match='at least one must be > 0'):
        dyn.MassProperties(**values)


def test_field_names_units_and_defaults():
    assert dyn.MassProperties.field_names() == (
        'input_inertia', 'flywheel_inertia', 'lever_inertia', 'lever_mass',
        'lever_com_distance', 'ram_mass', 'gravity')
    assert dyn.Loads.field_names() == ('cutting_force', 'ram_friction', 'cutting_length')
    assert dyn.MotorDrive.units() == {'speed_stiffness': 'N*m*s/rad', 'max_torque': 'N*m'}
    assert dyn.Loads.small_shaper().cutting_length < Geometry.paper().ram_stroke
