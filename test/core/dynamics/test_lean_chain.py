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
The lean chain (the motor stepper's equation of motion) gives the chain's numbers bit for bit.

In its Python form and compiled (qrm_ros.core.dynamics.drive_kernel), on random states with exact
zeros among them; and as the speed drive's efforts at a still stroke (stroke_efforts).
"""

import numpy as np
import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.dynamics.lean_chain import (lean_acceleration_of, lean_constants,
                                              lean_efforts_of, lean_ram_motion)
from qrm_ros.core.motor.motor_equation import EquationOfMotion
from qrm_ros.core.dynamics import stroke_efforts
from qrm_ros.core.dynamics.stroke_efforts import chain_with_stroke_screw, efforts_with_stroke_screw

pytestmark = pytest.mark.bits

GEOMETRY = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
# The masses the lean forms are checked with: the small shaper's, and one without a flywheel.
LEAN_MASSES = [MASS, dyn.MassProperties(
    input_inertia=0.05, flywheel_inertia=0.0, lever_mass=3.0, lever_inertia=0.4,
    lever_com_distance=0.2, ram_mass=12.0, gravity=9.81)]
LOADS = dyn.Loads.small_shaper()


def _bits(values):
    return [float(value).hex() for value in values]


def _chain_fixed(mass):
    """The chain's fixed arguments on floats, as the stepper holds them (motor_equation)."""
    return (dyn.SCALAR_OPS, *dyn.geometry_fields(GEOMETRY), mass.scalars())


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


def _random_effort_states(seed, count, radius):
    """Yield (index, offset, rate, speed, acceleration, load, angle), exact zeros among them."""
    rng = np.random.default_rng(seed)
    for index in range(count):
        # Exact zeros too (a shaft at rest, no ramp, no load): the signs of zeros agree.
        offset = 0.0 if index % 5 == 0 else float(rng.uniform(-0.99, 0.99)) * radius
        rate = 0.0 if index % 3 == 0 else float(rng.normal(0.0, 0.02))
        speed = 0.0 if index % 7 == 0 else float(rng.normal(0.0, 20.0))
        acceleration = 0.0 if index % 7 == 0 else float(rng.normal(0.0, 50.0))
        load = 0.0 if index % 4 == 0 else float(rng.normal(0.0, 1500.0))
        yield index, offset, rate, speed, acceleration, load, float(rng.uniform(-40.0, 40.0))


@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_lean_chain_gives_the_chains_numbers_bit_for_bit(mass):
    # The stepper's right-hand side and switch checks: the chain's formula, not a second one.
    fixed = _chain_fixed(mass)
    constants = lean_constants(GEOMETRY, mass)
    ram_motion = lean_ram_motion(constants)
    for offset, rate, angle, speed, torque, load in _random_states(9, 20000, 0.9, 4.0):
        chain = dyn.evaluate_chain(*fixed, offset, angle, speed, 0.0, rate, 0.0, 0.0)
        assert _bits([lean_acceleration_of(constants, offset, angle, speed, rate, torque,
                                           load)]) == _bits(
            [EquationOfMotion.acceleration(chain, torque, load)])
        assert _bits(ram_motion(offset, angle, speed, rate)) == _bits(
            [chain.ram_position, chain.ram_velocity])


def _kernel():
    pytest.importorskip('numba')
    from qrm_ros.core.dynamics import drive_kernel
    return drive_kernel


@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_lean_efforts_are_the_chains_bit_for_bit_in_python_and_compiled(mass):
    kernel = _kernel()
    constants = lean_constants(GEOMETRY, mass)
    array = np.array(constants)
    fixed = _chain_fixed(mass)
    for _, offset, rate, speed, acceleration, load, angle in _random_effort_states(
            12, 30000, GEOMETRY.coupling_radius):
        arguments = (offset, angle, speed, acceleration, rate, load)
        expected = _bits(dyn.evaluate_chain(*fixed, offset, angle, speed, acceleration, rate,
                                            0.0, load).efforts)
        assert _bits(lean_efforts_of(constants, *arguments)) == expected
        assert _bits(kernel.lean_efforts(array, *arguments)) == expected


@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_compiled_acceleration_gives_the_python_forms_numbers_bit_for_bit(mass):
    compiled = _kernel().lean_acceleration
    constants = lean_constants(GEOMETRY, mass)
    array = np.array(constants)
    for offset, rate, angle, speed, torque, load in _random_states(11, 50000, 0.99, 40.0):
        arguments = (offset, angle, speed, rate, torque, load)
        assert _bits([compiled(array, *arguments)]) == _bits(
            [lean_acceleration_of(constants, *arguments)])


@pytest.mark.parametrize('geometry', [GEOMETRY, Geometry(0.03, 0.06, 0.15, 0.25, 0.3)])
@pytest.mark.parametrize('mass', LEAN_MASSES)
def test_the_speed_drives_efforts_at_a_still_stroke_are_the_chains_bit_for_bit(
        geometry, mass, monkeypatch):
    # efforts_with_stroke_screw as the node calls it each tick: the lean chain answers where
    # the stroke is still, with the screw's force; the whole chain everywhere else.
    chain_calls = []

    def counted_chain(*arguments):
        chain_calls.append(arguments[-1])
        return dyn.evaluate_chain(*arguments)
    monkeypatch.setattr(stroke_efforts, 'evaluate_chain', counted_chain)
    for index, offset, rate, speed, acceleration, load, angle in _random_effort_states(
            21, 20000, geometry.coupling_radius):
        radius_rates = ((0.0, 0.0), (-0.0, 0.0), (0.002, -0.01))[index % 3]
        arguments = (geometry, mass, offset, angle, speed, acceleration, rate, 0.0, load,
                     *radius_rates)
        chain = chain_with_stroke_screw(*arguments)
        chain_calls.clear()
        efforts, screw_force = efforts_with_stroke_screw(*arguments)
        assert len(chain_calls) == (index % 3 == 2)  # the lean chain where the stroke is still
        assert type(efforts) is dyn.Efforts and type(screw_force) is float
        assert _bits([*efforts, screw_force]) == _bits([*chain.efforts,
                                                        chain.crank_radius_force])
    # What the lean chain leaves out goes to the whole chain: an offset acceleration, -0.0.
    for offset_acceleration in (0.5, -0.0):
        arguments = (geometry, mass, 0.01, 1.0, 6.0, 2.0, 0.003, offset_acceleration, -900.0,
                     0.0, 0.0)
        chain = chain_with_stroke_screw(*arguments)
        chain_calls.clear()
        efforts, screw_force = efforts_with_stroke_screw(*arguments)
        assert len(chain_calls) == 1
        assert _bits([*efforts, screw_force]) == _bits([*chain.efforts,
                                                        chain.crank_radius_force])
