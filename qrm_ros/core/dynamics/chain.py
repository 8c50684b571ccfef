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
Dynamics of the modified quick-return mechanism: efforts and inertia (pure numpy, no ROS).

Conventions, symbols and signs follow doc/dynamics.md. The chain is written with
its velocity coefficients (the partial derivatives d(phi)/d(theta), d(phi)/d(offset),
d(psi)/d(phi), dx/d(psi) and their own derivatives), because the efforts are defined through
them and because one formula then serves two callers: numpy arrays (``efforts`` over many
samples) and plain floats (the motor stepper's equation of motion, evaluated thousands of
times a second, where numpy's per-call cost would dominate). Every acceleration is a true
time derivative for any prescribed offset motion (offset_rate and offset_acceleration).
"""

from dataclasses import dataclass, fields
import functools
import math
from types import SimpleNamespace
from typing import Any, ClassVar, Dict, NamedTuple, Optional, Tuple, Type, Union

import numpy as np

from qrm_ros.core.common.checks import as_float
from qrm_ros.core.kinematics.geometry import check_offset, Geometry, KinematicsError
from qrm_ros.core.common.names import MOTOR_PREFIX
from qrm_ros.core.dynamics.physical_ranges import magnitude_problem
# The two arithmetic back ends of the chain: numpy for arrays, math for one sample (with the
# same bits: core.numerics.portable_math).
from qrm_ros.core.numerics.portable_math import ARRAY_OPS, SCALAR_OPS

__all__ = [
    'DynamicsError', 'Efforts', 'Loads', 'MassProperties', 'MotorDrive', 'checked_quantity',
    'efforts',
    'generalized_inertia', 'one_sample_ram_load', 'ram_load_force',
]

# A float, or a numpy array of them in vectorised use.
FloatOrArray = Union[float, np.ndarray]


class DynamicsError(KinematicsError):
    """A mass, load, drive or target the dynamics cannot take; the message names it."""


def checked_quantity(name: str, value: Any, unit: str, minimum: Optional[float] = None,
                     strict: bool = False) -> FloatOrArray:
    """Return value as float (or array), refusing non-numbers, non-finite and out-of-range."""
    checked = as_float(name, value, unit, DynamicsError, refuse_bool=True)
    if minimum is not None:
        array = np.asarray(checked)
        bad = array <= minimum if strict else array < minimum
        if np.any(bad):
            relation = '>' if strict else '>='
            shown = float(array[bad].flat[0]) if array.ndim else float(array)
            raise DynamicsError(f'{name} = {shown!r} {unit} is out of range: allowed '
                                f'{relation} {minimum:g} {unit}')
    return checked


@functools.cache
def _field_names(kind):
    # Once per class: the node asks at every tick (the efforts' one-sample path).
    return tuple(field.name for field in fields(kind))


class _Validated:
    """Field validation shared by the three parameter sets."""

    # name -> (unit, minimum or None, strictly greater)
    _LIMITS: ClassVar[dict[str, tuple[str, float | None, bool]]] = {}

    def __post_init__(self) -> None:
        for name, (unit, minimum, strict) in self._LIMITS.items():
            checked = checked_quantity(name, getattr(self, name), unit, minimum, strict)
            problem = magnitude_problem(name, float(np.max(np.abs(checked))), unit)
            if problem:
                raise DynamicsError(problem)
            object.__setattr__(self, name, checked)

    @classmethod
    def field_names(cls) -> Tuple[str, ...]:
        """Names of the fields, in order: node parameter names and metadata keys."""
        return _field_names(cls)  # type: ignore[arg-type]  # a class is hashable

    @classmethod
    def units(cls) -> Dict[str, str]:
        """Return the unit of each field (for parameter descriptions and help texts)."""
        return {name: cls._LIMITS[name][0] for name in cls.field_names()}

    @classmethod
    def lower_limits(cls) -> Dict[str, Tuple[Optional[float], bool]]:
        """(minimum, strictly greater) of each field, for parameter ranges."""
        return {name: cls._LIMITS[name][1:] for name in cls.field_names()}

    def as_dict(self) -> Dict[str, Any]:
        return {name: getattr(self, name) for name in self.field_names()}

    def scalars(self) -> Dict[str, Any]:
        """Return the fields as plain floats (the stepper's arithmetic); refuse array fields."""
        values = self.as_dict()
        for name, value in values.items():
            if np.ndim(value):
                raise DynamicsError(f'{name} must be a single number here, got an array')
        return values


@dataclass(frozen=True, eq=False)
class MassProperties(_Validated):
    """
    Inertias and masses of the moving bodies (kg m^2, kg, m, m/s^2), as dynamics.md.

    input_inertia includes the motor rotor and gearbox referred to the input shaft. At least
    one of input_inertia and flywheel_inertia must be > 0, so the generalised inertia of the
    chain never vanishes. Fields may be numpy arrays for design sweeps.
    """

    input_inertia: float
    flywheel_inertia: float
    lever_inertia: float
    lever_mass: float
    lever_com_distance: float
    ram_mass: float
    gravity: float = 9.81

    _LIMITS = {
        'input_inertia': ('kg*m^2', 0.0, False),
        'flywheel_inertia': ('kg*m^2', 0.0, False),
        'lever_inertia': ('kg*m^2', 0.0, False),
        'lever_mass': ('kg', 0.0, False),
        'lever_com_distance': ('m', None, False),
        'ram_mass': ('kg', 0.0, False),
        'gravity': ('m/s^2', 0.0, False),
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        if np.any(np.asarray(self.input_inertia) + self.flywheel_inertia <= 0.0):
            raise DynamicsError(
                f'input_inertia ({self.input_inertia!r} kg*m^2) and flywheel_inertia '
                f'({self.flywheel_inertia!r} kg*m^2) are both zero: at least one must be > 0')

    @classmethod
    def small_shaper(cls) -> 'MassProperties':
        """
        Return estimates for a small bench shaper of the paper's size (about 200 mm stroke).

        Sources of the numbers (rounded estimates, not measurements):

        * input_inertia 1.2 kg m^2: the rotor of a 0.75 kW 4-pole IEC 80 motor (catalogue
          value about 0.0021 kg m^2) seen through a 24:1 gearbox (1450 rpm to 60 rpm):
          0.0021 * 24^2. A real drive's flywheel effect sits mostly here.
        * flywheel_inertia 0.08 kg m^2: a steel bull gear of 250 mm diameter and 10 kg,
          m R^2 / 2.
        * lever_inertia 0.15 kg m^2, lever_mass 5 kg, lever_com_distance 0.15 m: a steel
          slotted lever 0.3 m long about its end pivot, m L^2 / 3, centre of mass mid-length.
        * ram_mass 20 kg: ram and tool head of a 7-inch (180 mm) bench shaper.
        """
        return cls(input_inertia=1.2, flywheel_inertia=0.08, lever_inertia=0.15,
                   lever_mass=5.0, lever_com_distance=0.15, ram_mass=20.0)


@dataclass(frozen=True, eq=False)
class Loads(_Validated):
    """
    Forces on the ram (N) and the workpiece length (m), as dynamics.md.

    cutting_length is centred on x = 0 and may not exceed the ram stroke (checked where the
    geometry is known: ``check_against``).
    """

    cutting_force: float
    ram_friction: float
    cutting_length: float

    _LIMITS = {
        'cutting_force': ('N', 0.0, False),
        'ram_friction': ('N', 0.0, False),
        'cutting_length': ('m', 0.0, False),
    }

    @classmethod
    def small_shaper(cls) -> 'Loads':
        """
        Return estimates for the small shaper of ``MassProperties.small_shaper``.

        cutting_force 400 N: 1 mm depth of cut at 0.2 mm feed in mild steel, specific cutting
        force about 2000 N/mm^2. ram_friction 20 N: friction coefficient 0.1 on the ram's
        weight (20 kg). cutting_length 0.15 m: a workpiece shorter than the 0.2 m stroke.
        """
        return cls(cutting_force=400.0, ram_friction=20.0, cutting_length=0.15)

    @classmethod
    def none(cls) -> 'Loads':
        """No cutting and no friction: free running."""
        return cls(cutting_force=0.0, ram_friction=0.0, cutting_length=0.0)

    def check_against(self, stroke: FloatOrArray) -> 'Loads':
        """Refuse a workpiece longer than the ram stroke (m); return self."""
        length = self.cutting_length  # a float but in vectorised use; this runs every tick
        if (length > stroke if type(length) is float
                else np.any(np.asarray(length) > stroke)):
            raise DynamicsError(f'cutting_length = {self.cutting_length!r} m is out of range: '
                                f'allowed 0 to the ram stroke, {stroke:.6g} m')
        return self


@dataclass(frozen=True, eq=False)
class MotorDrive(_Validated):
    """
    Motor law T = clip(speed_stiffness (speed_reference - input_speed), +-max_torque).

    speed_stiffness (N m s/rad) is the slope of an induction motor's torque-speed curve near
    its operating point, referred to the input shaft; a stiff motor, not the flywheel, then
    sets the speed fluctuation. max_torque (N m) is its pull-out torque there.
    """

    speed_stiffness: float
    max_torque: float

    _LIMITS = {
        'speed_stiffness': ('N*m*s/rad', 0.0, True),
        'max_torque': ('N*m', 0.0, True),
    }

    @classmethod
    def small_shaper(cls) -> 'MotorDrive':
        """
        Return estimates for the 0.75 kW 4-pole motor and 24:1 gearbox of the small shaper.

        Rated torque 4.9 N m at 5 % slip is 118 N m at the input shaft for a slip speed of
        0.05 * 157 rad/s / 24 = 0.327 rad/s: speed_stiffness = 118 / 0.327 = 360 N m s/rad.
        max_torque 250 N m: about 2.1 times rated, below a typical pull-out torque.
        """
        return cls(speed_stiffness=360.0, max_torque=250.0)


# Each parameter set's node parameters (shaper_sim, the recorded metadata, qrm_design's
# options): its field names behind this prefix.
PARAMETER_PREFIXES: dict[type[_Validated], str] = {
    MassProperties: '', Loads: '', MotorDrive: MOTOR_PREFIX}


def parameter_names(kind: Type[_Validated]) -> Tuple[str, ...]:
    """Return the node's names of a parameter set's fields (motor_speed_stiffness, ...)."""
    return tuple(PARAMETER_PREFIXES[kind] + name for name in kind.field_names())


class Efforts(NamedTuple):
    """What drives each joint, in the joint's positive sense (N m, N m, N m, N, N)."""

    # Each a float, or an array in vectorised use (Any: the callers know which).
    input_torque: Any
    flywheel_torque: Any
    lever_torque: Any
    ram_force: Any
    offset_force: Any


class Chain(NamedTuple):
    """Positions, rates, efforts and inertia of the chain at one instant (floats or arrays)."""

    flywheel_angle: Any
    flywheel_speed: Any
    flywheel_acceleration: Any
    lever_angle: Any
    lever_speed: Any
    lever_acceleration: Any
    ram_position: Any
    ram_velocity: Any
    ram_acceleration: Any
    efforts: Efforts
    generalized_inertia: Any
    ram_lever_arm: Any  # dx/d(theta) at a fixed offset, m/rad: F_ext's torque arm
    offset_coupling_inertia: Any  # d^2 T / d(theta_dot) d(offset_rate), kg m
    crank_radius_force: Any = 0.0  # the stroke screw's force on the crank pin, N along +r
    radius_coupling_inertia: Any = 0.0  # d^2 T / d(theta_dot) d(r_dot), kg m


def evaluate_chain(ops: SimpleNamespace, coupling_radius: FloatOrArray,
                   crank_radius: FloatOrArray, pivot_distance: FloatOrArray,
                   ram_height: FloatOrArray, crank_phase: FloatOrArray,
                   mass: Dict[str, Any], offset: FloatOrArray, input_angle: FloatOrArray,
                   input_speed: FloatOrArray, input_acceleration: FloatOrArray,
                   offset_rate: FloatOrArray, offset_acceleration: FloatOrArray,
                   external_ram_force: FloatOrArray, crank_radius_rate: FloatOrArray = 0.0,
                   crank_radius_acceleration: FloatOrArray = 0.0) -> Chain:
    """
    Evaluate the whole chain through its velocity coefficients; ``mass`` is a dict.

    ops is ARRAY_OPS (numpy arrays) or SCALAR_OPS (plain floats, one sample); the geometry's
    fields are geometry_fields' order.

    Coupling: n = |pin - O2|^2, phi_t = d(phi)/d(theta), phi_d = d(phi)/d(offset), and their
    derivatives; lever: m = |pin - O3|^2, psi_p = d(psi)/d(phi), psi_r = d(psi)/d(r) (the
    crank pin moved along the crank by the stroke screw: crank_radius_rate and
    crank_radius_acceleration, m/s and m/s^2, zero by default); ram: x = H tan(psi).
    """
    r1, r, h = coupling_radius, crank_radius, pivot_distance
    sin_t, cos_t = ops.sin(input_angle), ops.cos(input_angle)
    n = r1 * r1 + offset * offset + 2.0 * r1 * offset * sin_t
    phi_t = r1 * (r1 + offset * sin_t) / n
    phi_d = r1 * cos_t / n
    n2 = n * n
    phi_tt = r1 * offset * cos_t * (offset * offset - r1 * r1) / n2
    phi_td = -r1 * (sin_t * (r1 * r1 + offset * offset) + 2.0 * r1 * offset) / n2
    phi_dd = -2.0 * r1 * cos_t * (offset + r1 * sin_t) / n2
    flywheel_angle = input_angle + ops.atan2(offset * cos_t, r1 + offset * sin_t)
    crank_angle = flywheel_angle + crank_phase
    sin_c, cos_c = ops.sin(crank_angle), ops.cos(crank_angle)
    m = r * r + h * h + 2.0 * r * h * sin_c
    psi_p = -r * (r + h * sin_c) / m
    psi_pp = -r * h * cos_c * (h * h - r * r) / (m * m)
    below = h + r * sin_c  # > 0 because r < h: the lever stays within +-90 degrees
    tan_l = r * cos_c / below
    sec2 = 1.0 + tan_l * tan_l
    x_p = ram_height * sec2
    x_pp = 2.0 * ram_height * tan_l * sec2

    speed2 = input_speed * input_speed
    flywheel_speed = phi_t * input_speed + phi_d * offset_rate
    flywheel_acc = (phi_t * input_acceleration + phi_d * offset_acceleration + phi_tt * speed2
                    + 2.0 * phi_td * input_speed * offset_rate
                    + phi_dd * offset_rate * offset_rate)
    lever_speed = psi_p * flywheel_speed
    lever_acc = psi_p * flywheel_acc + psi_pp * flywheel_speed * flywheel_speed
    psi_r = h * cos_c / m
    if not (type(crank_radius_rate) is float and type(crank_radius_acceleration) is float
            and crank_radius_rate == 0.0 and crank_radius_acceleration == 0.0):
        # The stroke screw moves the crank pin: psi(phi, r) gains its terms in r' and r''.
        psi_pr = -h * (sin_c * (r * r + h * h) + 2.0 * r * h) / (m * m)
        psi_rr = -2.0 * h * cos_c * (r + h * sin_c) / (m * m)
        lever_speed = lever_speed + psi_r * crank_radius_rate
        lever_acc = (lever_acc + psi_r * crank_radius_acceleration
                     + 2.0 * psi_pr * flywheel_speed * crank_radius_rate
                     + psi_rr * crank_radius_rate * crank_radius_rate)
    ram_velocity = x_p * lever_speed
    ram_acc = x_p * lever_acc + x_pp * lever_speed * lever_speed

    gravity_torque = (mass['lever_mass'] * mass['gravity'] * mass['lever_com_distance']
                      * tan_l / ops.sqrt(sec2))
    ram_force = mass['ram_mass'] * ram_acc - external_ram_force
    lever_torque = mass['lever_inertia'] * lever_acc - gravity_torque + ram_force * x_p
    flywheel_torque = mass['flywheel_inertia'] * flywheel_acc + lever_torque * psi_p
    input_torque = mass['input_inertia'] * input_acceleration + flywheel_torque * phi_t
    offset_force = flywheel_torque * phi_d
    downstream = mass['flywheel_inertia'] + psi_p * psi_p * (
        mass['lever_inertia'] + mass['ram_mass'] * x_p * x_p)
    inertia = mass['input_inertia'] + phi_t * phi_t * downstream
    ram_lever_arm = x_p * psi_p * phi_t
    return Chain(flywheel_angle, flywheel_speed, flywheel_acc, ops.atan2(r * cos_c, below),
                 lever_speed, lever_acc, ram_height * tan_l, ram_velocity, ram_acc,
                 Efforts(input_torque, flywheel_torque, lever_torque, ram_force,
                         offset_force), inertia, ram_lever_arm, phi_t * phi_d * downstream,
                 lever_torque * psi_r, phi_t * psi_p * psi_r * (
                     mass['lever_inertia'] + mass['ram_mass'] * x_p * x_p))


def speed_drive_torque_of(sin_c: Any, cos_c: Any, r1: Any, r: Any, h: Any, height: Any,
                          cos0: Any, sin0: Any, offset: Any, clearance: Any, input_speed: Any,
                          ram_force: Any, flywheel_inertia: Any, lever_inertia: Any,
                          ram_mass: Any, gravity_moment: Any) -> Tuple[Any, Any]:
    """
    Return the chain's input torque and its slope d/d(phi_c) at a constant speed and offset.

    The ideal speed drive's case of ``evaluate_chain`` (input and offset accelerations and
    offset rate zero) written in the crank angle phi_c (sin_c, cos_c) for one ram force F
    (N): with the coupling's speed ratio w = d(phi)/d(theta) = S / r2 in the flywheel angle
    (kinematics._ram_speed_terms), x_c = dx/d(phi_c), psi_c = d(psi)/d(phi_c), the reduced inertia
    D = I_f + I_l psi_c^2 + m_ram x_c^2 (so M = I_in + w^2 D) and the gravity term
    g_c = psi_c m_l g l_com sin(psi),

        torque = speed^2 w^2 (w_c D + w D_c / 2) - w (g_c + F x_c),

    the chain's ``phi_t * flywheel_torque`` regrouped (d(M/2)/d(theta) speed^2 for the
    inertia). numpy only: qrm_ros.core.dynamics.torque_kernel compiles it for floats, and numpy
    runs it on arrays (the tests hold it to ``efforts``). clearance is (r1 - offset)(r1 + offset),
    gravity_moment m_l g l_com (N m), cos0 and sin0 those of the crank phase.
    """
    sin_f = sin_c * cos0 - cos_c * sin0  # flywheel angle phi = phi_c - crank phase
    cos_f = cos_c * cos0 + sin_c * sin0
    offset_cos = offset * cos_f
    root = np.sqrt(r1 * r1 - offset_cos * offset_cos)
    lift = offset * sin_f
    # 1 / r2 without cancellation: r2 = lift + S = clearance / (S - lift), so with
    # a = S + |lift| it is 1 / a for lift >= 0 and a / clearance below (no branch, so that
    # compiled for floats it stays a select).
    pin_sum = root + np.abs(lift)
    above = lift >= 0.0
    inverse_pin = above * (1.0 / pin_sum) + (1.0 - above) * (pin_sum / clearance)
    inverse_root = 1.0 / root
    ratio = root * inverse_pin
    factor = offset * clearance * inverse_root * inverse_pin * inverse_pin
    ratio1 = -factor * cos_f
    ratio2 = factor * (sin_f * (1.0 + (offset_cos * inverse_root) ** 2)
                       + 2.0 * offset_cos * cos_f * inverse_root)
    # Lever stage: x = H r cos / (h + r sin), psi_c = -r (r + h sin) / m.
    inverse_below = 1.0 / (h + r * sin_c)
    rise = h * sin_c + r
    bracket = h * h - 2.0 * r * r - h * r * sin_c
    scale = -height * r * inverse_below * inverse_below
    cos2 = cos_c * cos_c
    x_c = scale * rise
    x_cc = scale * inverse_below * cos_c * bracket
    x_ccc = scale * inverse_below * ((-sin_c * bracket - h * r * cos2)
                                     - 3.0 * r * cos2 * bracket * inverse_below)
    inverse_m = 1.0 / (r * r + h * h + 2.0 * r * h * sin_c)
    spread = r * h * (h * h - r * r) * inverse_m * inverse_m
    psi_c = -r * rise * inverse_m
    psi_cc = -spread * cos_c
    psi_ccc = spread * inverse_m * (sin_c * (r * r + h * h + 2.0 * r * h * sin_c)
                                    + 4.0 * r * h * cos2)
    # g_c = -K r^2 (h sin + r) cos m^(-3/2), K = gravity_moment.
    root_m = np.sqrt(inverse_m)
    lever_weight = -gravity_moment * r * r * inverse_m * root_m
    gravity_c = lever_weight * rise * cos_c
    gravity_cc = lever_weight * ((h * cos2 - rise * sin_c)
                                 - 3.0 * r * h * rise * cos2 * inverse_m)
    inertia = flywheel_inertia + lever_inertia * psi_c * psi_c + ram_mass * x_c * x_c
    inertia_c = 2.0 * (lever_inertia * psi_c * psi_cc + ram_mass * x_c * x_cc)
    inertia_cc = 2.0 * (lever_inertia * (psi_cc * psi_cc + psi_c * psi_ccc)
                        + ram_mass * (x_cc * x_cc + x_c * x_ccc))
    speed2 = input_speed * input_speed
    load = gravity_c + ram_force * x_c
    load_c = gravity_cc + ram_force * x_cc
    torque = (speed2 * ratio * ratio * (ratio1 * inertia + 0.5 * ratio * inertia_c)
              - ratio * load)
    slope = (speed2 * ratio * (2.0 * ratio1 * ratio1 * inertia
                               + ratio * (ratio2 * inertia + 2.5 * ratio1 * inertia_c
                                          + 0.5 * ratio * inertia_cc))
             - ratio1 * load - ratio * load_c)
    return torque, slope


def array_chain(geometry: Geometry, mass: MassProperties, offset: FloatOrArray,
                input_angle: FloatOrArray, input_speed: FloatOrArray = 0.0,
                input_acceleration: FloatOrArray = 0.0, offset_rate: FloatOrArray = 0.0,
                offset_acceleration: FloatOrArray = 0.0,
                external_ram_force: FloatOrArray = 0.0) -> Chain:
    """Return the whole chain on arrays (checked arguments; they broadcast)."""
    offset = check_offset(geometry, offset)
    arguments = [checked_quantity(name, value, unit) for name, value, unit in (
        ('input_angle', input_angle, 'rad'), ('input_speed', input_speed, 'rad/s'),
        ('input_acceleration', input_acceleration, 'rad/s^2'),
        ('offset_rate', offset_rate, 'm/s'),
        ('offset_acceleration', offset_acceleration, 'm/s^2'),
        ('external_ram_force', external_ram_force, 'N'))]
    return evaluate_chain(ARRAY_OPS, geometry.coupling_radius, geometry.crank_radius,
                          geometry.pivot_distance, geometry.ram_height, geometry.crank_phase,
                          mass.as_dict(), offset, *arguments)


def _scalar_result(values, kind):
    if all(np.ndim(value) == 0 for value in values):
        return kind(*(float(value) for value in values))
    return kind(*np.broadcast_arrays(*values))


def efforts(geometry: Geometry, mass: MassProperties, offset: FloatOrArray,
            input_angle: FloatOrArray, input_speed: FloatOrArray,
            input_acceleration: FloatOrArray = 0.0, offset_rate: FloatOrArray = 0.0,
            offset_acceleration: FloatOrArray = 0.0,
            external_ram_force: FloatOrArray = 0.0) -> Efforts:
    """
    Return what drives each joint, exactly, for a prescribed input and offset motion.

    external_ram_force is F_ext (N, along +x), e.g. ``ram_load_force``. Arguments broadcast;
    the result is an ``Efforts`` of floats or of equally shaped arrays.
    """
    arguments = (offset, input_angle, input_speed, input_acceleration, offset_rate,
                 offset_acceleration, external_ram_force)
    fixed = _scalar_set_up(geometry, mass)
    if fixed is not None and _one_sample(fixed[1], arguments):
        # One sample of floats (the node, every tick): math's functions, no array checks.
        return evaluate_chain(*fixed, *arguments).efforts
    chain = array_chain(geometry, mass, *arguments)
    return _scalar_result(chain.efforts, Efforts)


def geometry_fields(geometry: Geometry) -> Tuple[FloatOrArray, ...]:
    """Return the geometry's fields in the chain's order (evaluate_chain's arguments)."""
    return (geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance,
            geometry.ram_height, geometry.crank_phase)


# The chain's fixed arguments for one sample: math's functions, the geometry, the masses.
_ScalarSetUp = Tuple[SimpleNamespace, float, float, float, float, float, Dict[str, Any]]


@functools.lru_cache(maxsize=16)
def _scalar_set_up(geometry: Geometry, mass: MassProperties) -> Optional[_ScalarSetUp]:
    """
    Return the chain's fixed arguments for one-sample calls, or None if any is not a float.

    Both are frozen and hash by identity, so this runs once per pair of objects (the node
    keeps them between changes), not at every tick.
    """
    fields = geometry_fields(geometry)
    masses = mass.as_dict()
    if all(type(value) is float and math.isfinite(value)
           for value in (*fields, *masses.values())):
        return (SCALAR_OPS, *fields, masses)  # type: ignore[return-value]  # floats, checked
    return None


def _one_sample(coupling_radius, arguments):
    """Say whether all are finite floats and the offset one the coupling turns with."""
    return (all(type(value) is float and math.isfinite(value) for value in arguments)
            and abs(arguments[0]) < coupling_radius)


def generalized_inertia(geometry: Geometry, mass: MassProperties, offset: FloatOrArray,
                        input_angle: FloatOrArray) -> FloatOrArray:
    """M(theta, offset) of dynamics.md: input torque per unit input acceleration, kg m^2."""
    chain = array_chain(geometry, mass, offset, input_angle)
    value = chain.generalized_inertia
    return float(value) if np.ndim(value) == 0 else value


def one_sample_ram_load(cutting_force: float, cutting_length: float, ram_friction: float,
                        ram_position: float, ram_velocity: float) -> float:
    """
    ram_load_force on one sample of floats, the loads' fields given (N, m, N; m, m/s).

    Math and floats only: the speed drive's compiled sample (qrm_ros.core.dynamics.drive_kernel)
    calls it too.
    """
    cutting = ram_velocity < 0.0 and abs(ram_position) <= 0.5 * cutting_length
    direction = math.copysign(1.0, ram_velocity) if ram_velocity else 0.0
    return (cutting_force if cutting else 0.0) - ram_friction * direction


def ram_load_force(loads: 'Loads', ram_position: FloatOrArray, ram_velocity: FloatOrArray,
                   stroke: FloatOrArray) -> FloatOrArray:
    """
    F_ext on the ram (N, along +x): cutting force while cutting, and Coulomb friction.

    The tool faces -x: it cuts while the ram velocity is < 0 and |x| <= cutting_length / 2.
    Friction is -ram_friction sign(v), zero at rest. stroke (m) is the geometry's ram stroke,
    which the workpiece may not exceed.
    """
    loads.check_against(stroke)
    if type(ram_position) is float and type(ram_velocity) is float:  # one sample: the node
        return one_sample_ram_load(loads.cutting_force, loads.cutting_length,
                                   loads.ram_friction, ram_position, ram_velocity)
    position = np.asarray(ram_position, dtype=float)
    velocity = np.asarray(ram_velocity, dtype=float)
    cutting = (velocity < 0.0) & (np.abs(position) <= 0.5 * loads.cutting_length)
    force = np.where(cutting, loads.cutting_force, 0.0) - loads.ram_friction * np.sign(velocity)
    return float(force) if force.ndim == 0 else force
