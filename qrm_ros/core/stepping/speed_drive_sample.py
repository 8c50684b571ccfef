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
One sample of the ideal speed drive at its stepper's stamp: the joints' motion and efforts.

What the node publishes each tick under the speed drive: the kinematics core's state, the
ram's load (dynamics.ram_load_force) and the chain's efforts with the stroke screw's force
(stroke_efforts.efforts_with_stroke_screw). With the stroke still and one sample of finite
floats (nearly every tick), lean_chain.lean_speed_drive_sample does their operations in
their order at once, compiled (qrm_ros.core.dynamics.drive_kernel) once that is loaded: the same
numbers bit for bit, at a fraction of the cost, which an offline run (qrm_simulate) pays
hundreds of thousands of times. Elsewhere (the screw moving, anything not a finite float)
the core's general forms answer.
"""

import math
from typing import NamedTuple, Optional, Tuple

import numpy as np

from qrm_ros.core.dynamics.chain import Loads, MassProperties, ram_load_force
from qrm_ros.core.kinematics.geometry import Geometry, MechanismState
from qrm_ros.core.dynamics.lean_chain import lean_speed_drive_sample
from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.stepping.stepping import ShaperStepper
from qrm_ros.core.dynamics.stroke_efforts import efforts_with_stroke_screw, still_stroke_constants

__all__ = ['speed_drive_sample']

_FIVE_FLOATS = (float,) * 5


class _Prepared(NamedTuple):
    """What the lean form takes from one geometry, mass and loads (their objects)."""

    geometry: Geometry
    mass: MassProperties
    loads: Loads
    constants: Optional[Tuple[float, ...]]  # None: the lean form cannot answer
    compiled_constants: Optional[np.ndarray]  # the same as the compiled form takes them
    load_fields: Tuple[float, float, float]  # cutting_force, cutting_length, ram_friction


def _prepare(geometry: Geometry, mass: MassProperties, loads: Loads) -> _Prepared:
    """Return the lean form's constants and load fields (None if not all finite floats)."""
    constants = still_stroke_constants(geometry, mass)
    load_fields = (loads.cutting_force, loads.cutting_length, loads.ram_friction)
    if not all(type(value) is float and math.isfinite(value) for value in load_fields):
        constants = None
    return _Prepared(geometry, mass, loads, constants,
                     None if constants is None else np.array(constants, dtype=np.float64),
                     load_fields)


# The last prepared, found again by identity (the node's parameter sets are new objects
# whenever they change; hashing them at every tick cost more than the lean form).
_last_prepared: Optional[_Prepared] = None


def speed_drive_sample(stepper: ShaperStepper, mass: MassProperties, loads: Loads
                       ) -> Tuple[Optional[MechanismState], Tuple[float, ...]]:
    """
    Return (the core's state or None, the sample) at the stepper's present stamp.

    The sample is lean_chain.SPEED_DRIVE_SAMPLE_FIELDS. The state is None where the lean
    form answered (it holds no accelerations; whoever needs them asks the core).
    """
    global _last_prepared
    stroke = stepper.stroke
    loads.check_against(max(stroke.stroke, stroke.command))
    radius_rate, radius_acceleration = stroke.crank_radius_rates()
    geometry = stepper.geometry
    prepared = _last_prepared
    if (prepared is None or prepared.geometry is not geometry or prepared.mass is not mass
            or prepared.loads is not loads):
        _last_prepared = prepared = _prepare(geometry, mass, loads)
    constants = prepared.constants
    arguments = (stepper.offset, stepper.input_angle, stepper.input_speed,
                 stepper.input_acceleration, stepper.offset_rate)
    if (constants is not None and radius_rate == 0.0 and radius_acceleration == 0.0
            and tuple(map(type, arguments)) == _FIVE_FLOATS
            and all(map(math.isfinite, arguments)) and abs(arguments[0]) < constants[0]):
        compiled = COMPILED_DRIVE_KERNEL.module
        if compiled is not None:
            return None, compiled.lean_speed_drive(prepared.compiled_constants,
                                                   *prepared.load_fields, *arguments)
        return None, lean_speed_drive_sample(constants, *prepared.load_fields, *arguments)
    sample = stepper.mechanism_state()
    offset, input_angle, input_speed, input_acceleration, offset_rate = arguments
    ram_force = ram_load_force(loads, sample.ram_position, sample.ram_velocity,
                               max(stroke.stroke, stroke.command))
    efforts, screw_force = efforts_with_stroke_screw(
        geometry, mass, offset, input_angle, input_speed, input_acceleration, offset_rate,
        0.0, ram_force, radius_rate, radius_acceleration)
    values = (sample.flywheel_angle, sample.flywheel_speed, sample.lever_angle,
              sample.lever_speed, sample.ram_position, sample.ram_velocity, *efforts,
              screw_force)
    return sample, tuple(float(value) for value in values)
