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
What the motor drive's equation of motion is made of: masses, ram loads, the motor's law.

The input's acceleration is (motor torque - bias) / M (doc/dynamics.md): the chain's
efforts at zero input acceleration less the ram load's torque, over the generalised
inertia. ``EquationOfMotion`` holds one set of masses, loads and motor with everything the
stepper derives from them once (the chain's fixed arguments, the lean chain's constants,
the load's switch angles per offset), and the rules that pick the load and the motor's
torque in a segment's mode, and the direction of a shaft at rest (the stall rule).
"""

from types import SimpleNamespace
from typing import Any, Callable, cast, Dict, List, Optional, Tuple

import numpy as np

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry, TWO_PI
from qrm_ros.core.dynamics.lean_chain import lean_constants, lean_ram_motion
from qrm_ros.core.dynamics.physical_ranges import (motor_speed_band_problem,
                                                   motor_time_constant_problem)
from qrm_ros.core.dynamics.speed_drive import load_switch_angles

__all__ = ['ChainFixed', 'EquationOfMotion', 'sign']

# dynamics.evaluate_chain's fixed arguments on floats: math's functions, the geometry's five
# fields, the masses.
ChainFixed = Tuple[SimpleNamespace, float, float, float, float, float, Dict[str, Any]]


def sign(value: float) -> int:
    """Return the sign of value as an int: 1, -1 or 0."""
    return int(value > 0.0) - int(value < 0.0)


class EquationOfMotion:
    """
    The motor drive's masses, loads and motor on one geometry, and what follows from them.

    motor=None runs the shaft free (no motor torque).
    """

    def __init__(self, geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                 motor: Optional[dyn.MotorDrive],
                 longest_stroke: Optional[float] = None) -> None:
        self.geometry = geometry
        self.mass = mass
        # The chain's fixed arguments: math's functions, the geometry, the masses as floats.
        self.fixed = cast(ChainFixed, (dyn.SCALAR_OPS, *dyn.geometry_fields(geometry),
                                       mass.scalars()))
        self.lean_constants = lean_constants(geometry, mass)
        self.lean_array = np.array(self.lean_constants)  # the compiled forms take an array
        self.ram_motion: Callable[[float, float, float, float], Tuple[float, float]] = (
            lean_ram_motion(self.lean_constants))
        self._switch_angles_at: Dict[float, List[float]] = {}
        # The workpiece fits the longer of the strokes in force and commanded (the node's
        # rule while the stroke screw moves).
        self.loads = loads.check_against(geometry.ram_stroke if longest_stroke is None
                                         else max(geometry.ram_stroke, longest_stroke))
        loads.scalars()
        self.motor = motor
        if motor is not None:
            motor.scalars()
            too_stiff = (motor_time_constant_problem(mass.input_inertia, mass.flywheel_inertia,
                                                     motor.speed_stiffness)
                         or motor_speed_band_problem(motor.speed_stiffness, motor.max_torque))
            if too_stiff:
                raise dyn.DynamicsError(too_stiff)

    def chain(self, offset: float, angle: float, speed: float, offset_rate: float,
              crank_radius_rate: float = 0.0,
              crank_radius_acceleration: float = 0.0) -> dyn.Chain:
        """Evaluate the chain at zero input acceleration; all arguments plain floats."""
        return dyn.evaluate_chain(*self.fixed, offset, angle, speed, 0.0, offset_rate, 0.0, 0.0,
                                  crank_radius_rate, crank_radius_acceleration)

    def speed_after_rate_jump(self, offset: float, angle: float, speed: float,
                              old_rate: float, rate: float, old_radius_rate: float = 0.0,
                              radius_rate: float = 0.0) -> float:
        """
        Return the input speed (rad/s) after the offset and crank radius rates jump.

        The offset rate from old_rate to rate (m/s), the crank radius' from old_radius_rate
        to radius_rate (m/s): impulses on the offset and the crank pin alone keep the
        input's generalised momentum, M theta' + C_offset offset' + C_r r'.
        """
        chain = self.chain(offset, angle, speed, old_rate)
        if rate != old_rate:
            speed -= chain.offset_coupling_inertia * (rate - old_rate) / (
                chain.generalized_inertia)
        if radius_rate != old_radius_rate:
            speed -= chain.radius_coupling_inertia * (radius_rate - old_radius_rate) / (
                chain.generalized_inertia)
        return speed

    def motor_torque(self, reference: float, speed: float, saturation: int) -> float:
        """Return the motor's torque (N m): its law, or +-max_torque when saturated."""
        if self.motor is None:
            return 0.0
        if saturation:
            return saturation * self.motor.max_torque
        return self.motor.speed_stiffness * (reference - speed)

    def saturation_of(self, reference: float, speed: float) -> int:
        """Return 1 or -1 if the motor's law asks for more than max_torque that way, else 0."""
        if self.motor is None:
            return 0
        demand = self.motor.speed_stiffness * (reference - speed)
        return sign(demand) if abs(demand) >= self.motor.max_torque else 0

    def applied_motor_torque(self, reference: float, speed: float) -> float:
        """Return the torque the motor applies at this reference and speed (N m)."""
        return self.motor_torque(reference, speed, self.saturation_of(reference, speed))

    def ram_load(self, direction: int, in_work: bool) -> float:
        """Return the ram load (N along +x) met moving in direction (+-1), in the work or not."""
        loads = self.loads
        cutting = loads.cutting_force if direction < 0 and in_work else 0.0
        return cutting - loads.ram_friction * direction

    @staticmethod
    def acceleration(chain: dyn.Chain, torque: float, load: float) -> float:
        """Return the input speed's rate, rad/s^2, under the torque (N m) and ram load (N)."""
        bias = chain.efforts.input_torque - load * chain.ram_lever_arm
        return (torque - bias) / chain.generalized_inertia

    def switch_angles(self, offset: float) -> Optional[List[float]]:
        """Input angles (rad, in [0, 2 pi)) of the load's switches at this offset (cached)."""
        angles = self._switch_angles_at.get(offset)
        if angles is None:
            found = load_switch_angles(self.geometry, self.loads, offset)
            angles = sorted(float(angle) % TWO_PI for angle in found)
            self._switch_angles_at = {offset: angles}
        return angles

    def at_rest(self, chain: dyn.Chain, angle: float, reference: float, speed_command: float,
                velocity: float, in_work: bool,
                direction: int) -> Tuple[int, int, Optional[str]]:
        """
        Input speed zero: return (spin, direction, stall reason) by the stall rule.

        The load seen by each direction of motion is the one that motion would meet (friction
        against it; the cutting force if the ram would move toward -x inside the workpiece).
        The shaft moves forward (spin 1, the ram's direction then) if the motor's torque at
        zero speed beats the forward load's torque, backward likewise, else it is held at
        rest (spin 0, direction kept). Held with a non-zero speed reference or command is a
        stall, and the reason says why.
        """
        torque = self.motor_torque(reference, 0.0, self.saturation_of(reference, 0.0))
        accelerations = {}
        for spin in (1, -1):
            moving = sign(velocity) or sign(chain.ram_lever_arm * spin) or spin
            load = self.ram_load(moving, in_work)
            accelerations[spin] = (self.acceleration(chain, torque, load), moving)
        for spin in (1, -1):
            acceleration, moving = accelerations[spin]
            if acceleration * spin > 0.0:
                return spin, moving, None
        if reference == 0.0 and speed_command == 0.0:
            return 0, direction, None
        needed = chain.generalized_inertia * -accelerations[sign(reference) or 1][0] + torque
        return 0, direction, (
            f'stalled at input angle {angle:.6g} rad: the motor gives {torque:.6g} N*m at '
            f'zero speed (max_torque '
            f'{self.motor.max_torque if self.motor else 0.0:.6g} N*m), the load needs '
            f'{needed:.6g} N*m to turn the input (cutting_force '
            f'{self.loads.cutting_force:.6g} N, ram_friction '
            f'{self.loads.ram_friction:.6g} N)')
