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
The speed drive's sample (core.stepping.speed_drive_sample) is the core's state, load and efforts.

Bit for bit, in the lean form's Python and compiled versions, against what the node computed
with the general forms: mechanism_state.state, dynamics.ram_load_force and
stroke_efforts.efforts_with_stroke_screw, on random steppers (exact zeros among them, the
workpiece's edges crossed, the tool in and out of the cut), and the general forms where the
stroke screw moves.
"""

import numpy as np
import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.dynamics.lean_chain import SPEED_DRIVE_SAMPLE_FIELDS
from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.stepping.speed_drive_sample import speed_drive_sample
from qrm_ros.core.stepping.stepping import ShaperStepper
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp
from qrm_ros.core.dynamics.stroke_efforts import efforts_with_stroke_screw

pytestmark = pytest.mark.bits

GEOMETRIES = [Geometry.paper(), Geometry(0.03, 0.06, 0.15, 0.25, 0.3)]
MASSES = [dyn.MassProperties.small_shaper(), dyn.MassProperties(
    input_inertia=0.05, flywheel_inertia=0.0, lever_mass=3.0, lever_inertia=0.4,
    lever_com_distance=0.2, ram_mass=12.0, gravity=9.81)]


def _bits(values):
    return [float(value).hex() for value in values]


def _general(stepper, mass, loads):
    """The sample as the node computed it with the general forms."""
    sample = stepper.mechanism_state()
    stroke = stepper.stroke
    radius_rate, radius_acceleration = stroke.crank_radius_rates()
    ram_force = dyn.ram_load_force(loads, sample.ram_position, sample.ram_velocity,
                                   max(stroke.stroke, stroke.command))
    efforts, screw_force = efforts_with_stroke_screw(
        stepper.geometry, mass, stepper.offset, stepper.input_angle, stepper.input_speed,
        stepper.input_acceleration, stepper.offset_rate, 0.0, ram_force, radius_rate,
        radius_acceleration)
    return (sample.flywheel_angle, sample.flywheel_speed, sample.lever_angle,
            sample.lever_speed, sample.ram_position, sample.ram_velocity, *efforts, screw_force)


def _random_steppers(geometry, seed, count):
    """Yield steppers at random states: exact zeros, ramps under way, both directions."""
    rng = np.random.default_rng(seed)
    radius = geometry.coupling_radius
    for index in range(count):
        offset = 0.0 if index % 5 == 0 else float(rng.uniform(-0.99, 0.99)) * radius
        speed = 0.0 if index % 7 == 0 else float(rng.normal(0.0, 20.0))
        stepper = ShaperStepper(geometry, speed, offset, 50.0, 0.02)
        stepper.restore(1_000_000_000, float(rng.uniform(-np.pi, np.pi)), speed, offset)
        if index % 3 == 1:  # an offset ramp under way: an offset rate
            stepper.set_offset_command(float(rng.uniform(-0.99, 0.99)) * radius)
        if index % 4 == 1:  # a speed ramp under way: an input acceleration
            stepper.set_speed_command(float(rng.normal(0.0, 20.0)))
        yield stepper


@pytest.fixture(params=['python', 'compiled'])
def kernel(request, monkeypatch):
    """The lean form in Python (no compiled kernel) or compiled."""
    if request.param == 'python':
        monkeypatch.setattr(COMPILED_DRIVE_KERNEL, 'module', None)
    else:
        pytest.importorskip('numba')
        from qrm_ros.core.dynamics import drive_kernel
        monkeypatch.setattr(COMPILED_DRIVE_KERNEL, 'module', drive_kernel)
    return request.param


@pytest.mark.parametrize('geometry', GEOMETRIES)
@pytest.mark.parametrize('mass', MASSES)
@pytest.mark.parametrize('loads', [dyn.Loads.small_shaper(), dyn.Loads.none(),
                                   dyn.Loads(cutting_force=900.0, ram_friction=35.0,
                                             cutting_length=0.04)])
def test_the_lean_sample_is_the_general_forms_bit_for_bit(geometry, mass, loads, kernel):
    cutting = 0
    for stepper in _random_steppers(geometry, 31, 6000):
        state, sample = speed_drive_sample(stepper, mass, loads)
        assert state is None  # the lean form answered
        assert len(sample) == len(SPEED_DRIVE_SAMPLE_FIELDS)
        assert _bits(sample) == _bits(_general(stepper, mass, loads))
        cutting += sample[5] < 0.0 and abs(sample[4]) <= 0.5 * loads.cutting_length
    assert cutting > 100 or loads.cutting_length == 0.0  # the cut was among the samples


@pytest.mark.parametrize('geometry', GEOMETRIES)
def test_a_moving_stroke_screw_takes_the_general_forms(geometry, kernel):
    # The crank pin sliding: the chain with its radial terms, and the core's state.
    mass, loads = MASSES[0], dyn.Loads.none()
    stroke = StrokeRamp(geometry, 1.2 * geometry.crank_radius, float(geometry.ram_stroke), 0.01)
    stepper = ShaperStepper(geometry, 6.0, 0.005, 50.0, 0.02, stroke=stroke)
    stepper.advance_to(1_000_000_000)
    stepper.set_stroke_command(0.8 * stroke.stroke)
    stepper.advance_to(1_010_000_000)
    assert stroke.crank_radius_rates()[0] != 0.0
    state, sample = speed_drive_sample(stepper, mass, loads)
    assert state is not None and _bits(sample) == _bits(_general(stepper, mass, loads))
    assert _bits(sample[:6]) == _bits([state.flywheel_angle, state.flywheel_speed,
                                       state.lever_angle, state.lever_speed,
                                       state.ram_position, state.ram_velocity])
