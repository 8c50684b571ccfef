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
Closed forms the measurement compares with and the figures draw, beside the core's.

The flywheel's speed swing over a revolution (what the offset costs the flywheel) and the
speed drive's input torque split by cause (inertia, cutting, gravity and friction).
"""

from typing import Any, NamedTuple

import numpy as np

from qrm_ros.analysis.recorded_drive import Drive
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin


def flywheel_speed_swing(geometry: kin.Geometry, offset: float) -> float:
    """
    Max / min flywheel speed over a revolution at a steady input speed: the offset's cost.

    Eq. 4: w2 / w1 = r1 (r1 + d sin t) / (r1^2 + d^2 + 2 r1 d sin t) is monotonic in sin t
    for |d| < r1, so its extremes are at sin t = -+1: r1 / (r1 -+ |d|).
    """
    radius = geometry.coupling_radius
    return (radius + abs(offset)) / (radius - abs(offset))


class InputTorqueParts(NamedTuple):
    """The speed drive's input torque at a steady setting, split by cause (N m)."""

    total: np.ndarray
    inertia: np.ndarray  # the moving masses' speed changes alone: no gravity, no loads
    cutting: np.ndarray  # the cutting force's share: F_c dx/d(theta) while the tool cuts
    gravity_and_friction: np.ndarray  # the rest: the lever's weight and the ram's friction


def input_torque_parts(geometry: kin.Geometry, drive: Drive, offset: float,
                       input_angle: np.ndarray, input_speed: float) -> InputTorqueParts:
    """
    Split the input torque over input_angle (rad) at a steady input_speed (rad/s) by cause.

    The torque is linear in the masses, in gravity and in the ram force, so the parts add up
    to the total exactly: what the offset costs in inertia torque shows apart from the work.
    """
    motion = kin.state(geometry, offset, input_angle, input_speed)
    loads = drive.loads
    stroke = geometry.ram_stroke

    def torque(mass: dyn.MassProperties, ram_force: Any = 0.0) -> np.ndarray:
        return np.asarray(dyn.efforts(geometry, mass, offset, input_angle, input_speed,
                                      external_ram_force=ram_force).input_torque)
    total = torque(drive.mass, dyn.ram_load_force(loads, motion.ram_position,
                                                  motion.ram_velocity, stroke))
    weightless = dyn.MassProperties(**{**drive.mass.as_dict(), 'gravity': 0.0})
    inertia = torque(weightless)
    cutting_only = dyn.Loads(loads.cutting_force, 0.0, loads.cutting_length)
    cutting = torque(weightless, dyn.ram_load_force(cutting_only, motion.ram_position,
                                                    motion.ram_velocity, stroke)) - inertia
    return InputTorqueParts(total, inertia, cutting, total - inertia - cutting)
