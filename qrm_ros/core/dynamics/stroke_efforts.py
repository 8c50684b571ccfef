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
The efforts while the stroke screw moves the crank pin, and the screw's own force.

The chain (dynamics.evaluate_chain) carries the terms in the crank radius' rate and
acceleration; this module gives the node and the tests its efforts with them, and the
stroke screw's force on the crank pin, F_r = tau3 d(psi)/d(r) (N along +r, outward along
the crank), as doc/dynamics.md defines it. With the stroke still, F_r is what holds the pin
in its slot against the lever.
"""

import functools
import math
from typing import Any, Dict, Optional, Tuple

import numpy as np

from qrm_ros.core.dynamics.chain import (Chain, checked_quantity, Efforts, evaluate_chain,
                                         geometry_fields, MassProperties)
from qrm_ros.core.numerics.portable_math import ARRAY_OPS, SCALAR_OPS
from qrm_ros.core.kinematics.geometry import check_offset, FloatOrArray, Geometry
from qrm_ros.core.dynamics.lean_chain import (lean_constants, lean_efforts_of,
                                              lever_radius_coefficient_of)

__all__ = ['chain_with_stroke_screw', 'efforts_with_stroke_screw', 'lever_radius_coefficient',
           'still_stroke_constants']


# The arguments' types on the one-sample path (by type: numpy's float64 takes the other).
_EIGHT_FLOATS = (float,) * 8


@functools.lru_cache(maxsize=8)
def _masses(mass: MassProperties) -> Dict[str, Any]:
    """Return the masses as a dict, once per (frozen, identity-hashed) object."""
    return mass.as_dict()


@functools.lru_cache(maxsize=8)
def _float_fields(geometry: Geometry) -> Optional[Tuple[float, float, float, float, float]]:
    """Return the geometry's fields if all are finite floats (once per geometry object)."""
    r1, r, h, height, phase = geometry_fields(geometry)
    fields = (r1, r, h, height, phase)
    if all(type(value) is float and math.isfinite(value) for value in fields):
        return fields  # type: ignore[return-value]  # floats, checked
    return None


def chain_with_stroke_screw(geometry: Geometry, mass: MassProperties, offset: FloatOrArray,
                            input_angle: FloatOrArray, input_speed: FloatOrArray,
                            input_acceleration: FloatOrArray = 0.0,
                            offset_rate: FloatOrArray = 0.0,
                            offset_acceleration: FloatOrArray = 0.0,
                            external_ram_force: FloatOrArray = 0.0,
                            crank_radius_rate: FloatOrArray = 0.0,
                            crank_radius_acceleration: FloatOrArray = 0.0) -> Chain:
    """
    Return the whole chain with the crank radius moving (m/s, m/s^2) at geometry's radius.

    One sample of floats takes math's functions; anything else is checked and broadcast.
    """
    arguments = (input_angle, input_speed, input_acceleration, offset_rate,
                 offset_acceleration, external_ram_force, crank_radius_rate,
                 crank_radius_acceleration)
    scalar_fields = _float_fields(geometry)
    if (scalar_fields is not None and type(offset) is float
            and abs(offset) < scalar_fields[0]
            and tuple(map(type, arguments)) == _EIGHT_FLOATS
            and all(map(math.isfinite, arguments))):
        # One sample of floats (the node, every tick): math's functions, no array checks.
        return evaluate_chain(SCALAR_OPS, *scalar_fields, _masses(mass), offset, *arguments)
    r1, r, h, height, phase = geometry_fields(geometry)
    offset = check_offset(geometry, offset)
    units = ('rad', 'rad/s', 'rad/s^2', 'm/s', 'm/s^2', 'N', 'm/s', 'm/s^2')
    names = ('input_angle', 'input_speed', 'input_acceleration', 'offset_rate',
             'offset_acceleration', 'external_ram_force', 'crank_radius_rate',
             'crank_radius_acceleration')
    checked = [np.asarray(checked_quantity(name, value, unit), dtype=float)
               for name, value, unit in zip(names, arguments, units)]
    return evaluate_chain(ARRAY_OPS, r1, r, h, height, phase, _masses(mass),
                          np.asarray(offset, dtype=float), *checked)


def efforts_with_stroke_screw(*arguments: Any, **keywords: Any) -> Tuple[Efforts, Any]:
    """
    Return (the joints' Efforts, the stroke screw's force in N along +r).

    Arguments as chain_with_stroke_screw's; floats in, floats out.
    """
    if len(arguments) == 11 and not keywords:  # the node's call, every tick
        still = _still_stroke_efforts(*arguments)
        if still is not None:
            return still
    chain = chain_with_stroke_screw(*arguments, **keywords)
    efforts, force = chain.efforts, chain.crank_radius_force
    if type(force) is float:  # the one-sample path: floats throughout
        return efforts, force
    if all(np.ndim(value) == 0 for value in (*efforts, force)):
        return Efforts(*(float(value) for value in efforts)), float(force)
    shaped = np.broadcast_arrays(*efforts, force)
    return Efforts(*shaped[:5]), shaped[5]


@functools.lru_cache(maxsize=8)
def still_stroke_constants(geometry: Geometry,
                           mass: MassProperties) -> Optional[Tuple[float, ...]]:
    """Return lean_chain's constants if the geometry's fields are finite floats, else None."""
    return None if _float_fields(geometry) is None else lean_constants(geometry, mass)


def _still_stroke_efforts(geometry: Geometry, mass: MassProperties, offset: Any,
                          *arguments: Any) -> Optional[Tuple[Efforts, float]]:
    """
    Return efforts_with_stroke_screw's answer by the lean chain where it is the chain's.

    That is one sample of finite floats with the stroke still and no offset acceleration
    (+0.0): there lean_chain.lean_efforts_of does the chain's operations in its order, less
    the terms it leaves out (the chain's numbers bit for bit, at under half its cost), and
    the screw's force is the lever torque times d(psi)/d(r) at the chain's flywheel angle,
    as the chain computes it. None elsewhere (the chain answers).
    """
    constants = still_stroke_constants(geometry, mass)
    if (constants is None or type(offset) is not float or not abs(offset) < constants[0]
            or tuple(map(type, arguments)) != _EIGHT_FLOATS
            or not all(map(math.isfinite, arguments))):
        return None
    (input_angle, input_speed, input_acceleration, offset_rate, offset_acceleration,
     external_ram_force, crank_radius_rate, crank_radius_acceleration) = arguments
    if (crank_radius_rate != 0.0 or crank_radius_acceleration != 0.0
            or offset_acceleration != 0.0 or math.copysign(1.0, offset_acceleration) < 0.0):
        return None
    efforts = lean_efforts_of(constants, offset, input_angle, input_speed, input_acceleration,
                              offset_rate, external_ram_force)
    r1 = constants[0]
    flywheel_angle = input_angle + math.atan2(offset * math.cos(input_angle),
                                              r1 + offset * math.sin(input_angle))
    return Efforts(*efforts), efforts[2] * lever_radius_coefficient(geometry, flywheel_angle)


def lever_radius_coefficient(geometry: Geometry, flywheel_angle: float) -> float:
    """
    Return d(psi)/d(r) (rad/m) at a flywheel angle: h cos(phi_c) / |pin - O3|^2.

    The stroke screw's force is the lever torque times this (with the stroke still: the
    motor stepper's efforts, which carry the lever torque).
    """
    crank_angle = flywheel_angle + float(geometry.crank_phase)
    return lever_radius_coefficient_of(float(geometry.crank_radius),
                                       float(geometry.pivot_distance), math.cos(crank_angle),
                                       math.sin(crank_angle))
