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
The chain on plain floats, lean: the motor stepper's equation of motion (no numpy).

``dynamics.evaluate_chain`` serves arrays and floats alike; the motor stepper evaluates it
thousands of times a second on floats, where the named tuples, the mass dict and the terms
multiplied by an exact zero cost more than the arithmetic. These are the chain's own
operations in its order with those left out, so they give its numbers bit for bit (the
tests hold them to it). Math functions and floats only: qrm_ros.core.dynamics.drive_kernel compiles
``lean_acceleration_of`` and ``lean_efforts_of`` (numba, no fast-math), which give the same
numbers bit for bit too.
"""

import math
from typing import Callable, Sequence, Tuple

from qrm_ros.core.dynamics.chain import MassProperties, one_sample_ram_load
from qrm_ros.core.kinematics.geometry import Geometry

__all__ = ['coupling_and_crank', 'lean_acceleration_of', 'lean_coefficients', 'lean_constants',
           'lean_efforts_of', 'lean_ram_motion', 'lean_speed_drive_sample', 'LeanConstants',
           'lever_radius_coefficient_of', 'SPEED_DRIVE_SAMPLE_FIELDS']

# The constants (lean_constants' tuple; the compiled forms take them as a float64 array).
LeanConstants = Sequence[float]


def lean_constants(geometry: Geometry, mass: MassProperties) -> Tuple[float, ...]:
    """
    Return the lean chain's constants: the geometry, the masses, and their fixed groupings.

    A tuple of floats in ``lean_coefficients``' order (qrm_ros.core.dynamics.drive_kernel takes
    them as an array); the groupings are the chain's own sub-expressions that hold the geometry
    alone, grouped as it groups them.
    """
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    height = geometry.ram_height
    fields = mass.scalars()
    return (r1, r, h, height, geometry.crank_phase, fields['input_inertia'],
            fields['flywheel_inertia'], fields['lever_inertia'], fields['ram_mass'],
            fields['lever_mass'] * fields['gravity'] * fields['lever_com_distance'],
            r1 * r1, 2.0 * r1, r * r + h * h, 2.0 * r * h, -r, -r * h, h * h - r * r,
            2.0 * height, -2.0 * r1)


def coupling_and_crank(constants: LeanConstants, radius: float, offset: float,
                       angle: float) -> Tuple[float, ...]:
    """
    Return the coupling's velocity coefficients and the crank's direction at (offset, angle).

    (phi_t, phi_d, phi_tt, phi_td, phi_dd, sin_c, cos_c, tan_l), with the crank radius given
    (m): the head shared by the lean forms at a still stroke and by the chain written out
    for a moving one (qrm_ros.core.motor.motor_stroke), so the two cannot drift apart.
    """
    r1, h, phase = constants[0], constants[2], constants[4]
    r1_r1, two_r1, minus_two_r1 = constants[10], constants[11], constants[18]
    sin_t, cos_t = math.sin(angle), math.cos(angle)
    n = r1_r1 + offset * offset + two_r1 * offset * sin_t
    phi_t = r1 * (r1 + offset * sin_t) / n
    phi_d = r1 * cos_t / n
    crank_angle = angle + math.atan2(offset * cos_t, r1 + offset * sin_t) + phase
    sin_c, cos_c = math.sin(crank_angle), math.cos(crank_angle)
    tan_l = radius * cos_c / (h + radius * sin_c)
    n2 = n * n
    phi_tt = r1 * offset * cos_t * (offset * offset - r1_r1) / n2
    phi_td = -r1 * (sin_t * (r1_r1 + offset * offset) + two_r1 * offset) / n2
    phi_dd = minus_two_r1 * cos_t * (offset + r1 * sin_t) / n2
    return phi_t, phi_d, phi_tt, phi_td, phi_dd, sin_c, cos_c, tan_l


def lean_coefficients(constants: LeanConstants, offset: float,
                      angle: float) -> Tuple[float, ...]:
    """
    Return the masses and the chain's velocity coefficients at (offset, angle).

    (input_inertia, flywheel_inertia, lever_inertia, ram_mass, lever_weight, phi_t, phi_d,
    phi_tt, phi_td, phi_dd, psi_p, psi_pp, tan_l, sec2, x_p, x_pp): the constants and the
    part of the chain that hold the configuration alone, shared by ``lean_acceleration_of``
    and ``lean_efforts_of`` (and compiled into them, qrm_ros.core.dynamics.drive_kernel).
    """
    (_, r, h, height, _, input_inertia, flywheel_inertia, lever_inertia, ram_mass,
     lever_weight, _, _, r_h, two_r_h, minus_r, minus_r_h, h_h_r_r, two_height,
     _) = constants
    phi_t, phi_d, phi_tt, phi_td, phi_dd, sin_c, cos_c, tan_l = coupling_and_crank(
        constants, r, offset, angle)
    m = r_h + two_r_h * sin_c
    psi_p = minus_r * (r + h * sin_c) / m
    psi_pp = minus_r_h * cos_c * h_h_r_r / (m * m)
    sec2 = 1.0 + tan_l * tan_l
    return (input_inertia, flywheel_inertia, lever_inertia, ram_mass, lever_weight, phi_t,
            phi_d, phi_tt, phi_td, phi_dd, psi_p, psi_pp, tan_l, sec2, height * sec2,
            two_height * tan_l * sec2)


def lean_acceleration_of(constants: LeanConstants, offset: float, angle: float, speed: float,
                         offset_rate: float, torque: float, load: float) -> float:
    """
    Return the input acceleration (rad/s^2) from the equation of motion; plain floats.

    The input torque and ram load given, at zero input and offset acceleration; constants
    from ``lean_constants``. The chain's own operations in its order, with what it does not
    need left out (terms times an exact zero, the lever angle, the named tuples, the mass
    dict), so it gives its numbers bit for bit (a test holds it to it) at under half its
    cost.
    """
    (input_inertia, flywheel_inertia, lever_inertia, ram_mass, lever_weight, phi_t, phi_d,
     phi_tt, phi_td, phi_dd, psi_p, psi_pp, tan_l, sec2, x_p,
     x_pp) = lean_coefficients(constants, offset, angle)
    flywheel_speed = phi_t * speed + phi_d * offset_rate
    flywheel_acc = (phi_tt * (speed * speed) + 2.0 * phi_td * speed * offset_rate
                    + phi_dd * offset_rate * offset_rate)
    lever_speed = psi_p * flywheel_speed
    lever_acc = psi_p * flywheel_acc + psi_pp * flywheel_speed * flywheel_speed
    ram_force = ram_mass * (x_p * lever_acc + x_pp * lever_speed * lever_speed)
    lever_torque = (lever_inertia * lever_acc - lever_weight * tan_l / math.sqrt(sec2)
                    + ram_force * x_p)
    flywheel_torque = flywheel_inertia * flywheel_acc + lever_torque * psi_p
    inertia = input_inertia + phi_t * phi_t * (
        flywheel_inertia + psi_p * psi_p * (lever_inertia + ram_mass * x_p * x_p))
    bias = flywheel_torque * phi_t - load * (x_p * psi_p * phi_t)
    return (torque - bias) / inertia


def lean_efforts_of(constants: LeanConstants, offset: float, angle: float, speed: float,
                    acceleration: float, offset_rate: float,
                    load: float) -> Tuple[float, float, float, float, float]:
    """
    Return the chain's Efforts fields as a tuple, at zero offset acceleration; plain floats.

    (input torque, flywheel torque, lever torque, ram force, offset force) under the ram
    load (N), constants from ``lean_constants``: every operation of the chain that they
    depend on, in its order (the offset acceleration's zero term kept, so even the signs of
    zeros agree), none of the rest; the chain's numbers bit for bit (a test holds them to
    it).
    """
    (input_inertia, flywheel_inertia, lever_inertia, ram_mass, lever_weight, phi_t, phi_d,
     phi_tt, phi_td, phi_dd, psi_p, psi_pp, tan_l, sec2, x_p,
     x_pp) = lean_coefficients(constants, offset, angle)
    flywheel_speed = phi_t * speed + phi_d * offset_rate
    flywheel_acc = (phi_t * acceleration + phi_d * 0.0 + phi_tt * (speed * speed)
                    + 2.0 * phi_td * speed * offset_rate + phi_dd * offset_rate * offset_rate)
    lever_speed = psi_p * flywheel_speed
    lever_acc = psi_p * flywheel_acc + psi_pp * flywheel_speed * flywheel_speed
    ram_force = ram_mass * (x_p * lever_acc + x_pp * lever_speed * lever_speed) - load
    lever_torque = (lever_inertia * lever_acc - lever_weight * tan_l / math.sqrt(sec2)
                    + ram_force * x_p)
    flywheel_torque = flywheel_inertia * flywheel_acc + lever_torque * psi_p
    return (input_inertia * acceleration + flywheel_torque * phi_t, flywheel_torque,
            lever_torque, ram_force, flywheel_torque * phi_d)


def lean_ram_motion(constants: LeanConstants) -> Callable[[float, float, float, float],
                                                          Tuple[float, float]]:
    """
    Return ram_motion(offset, angle, speed, offset_rate): the ram's (position m, velocity m/s).

    The stepper's switch checks' lean evaluation of ``dynamics.evaluate_chain`` on plain
    floats, constants from ``lean_constants``: at zero input and offset acceleration, the
    chain's numbers bit for bit (a test holds them to it) at a quarter of its cost.
    """
    (r1, r, h, height, phase, *_, r1_r1, two_r1, r_h, two_r_h, minus_r, _, _, _,
     _) = constants
    sin, cos, atan2 = math.sin, math.cos, math.atan2

    # The coupling and the lever's angle as lean_coefficients starts (a call to it would
    # cost about a tenth of the right-hand side, and it computes more than this needs).
    def ram_motion(offset, angle, speed, offset_rate):
        sin_t, cos_t = sin(angle), cos(angle)
        n = r1_r1 + offset * offset + two_r1 * offset * sin_t
        crank_angle = angle + atan2(offset * cos_t, r1 + offset * sin_t) + phase
        sin_c = sin(crank_angle)
        tan_l = r * cos(crank_angle) / (h + r * sin_c)
        psi_p = minus_r * (r + h * sin_c) / (r_h + two_r_h * sin_c)
        flywheel_speed = r1 * (r1 + offset * sin_t) / n * speed + r1 * cos_t / n * offset_rate
        return height * tan_l, height * (1.0 + tan_l * tan_l) * (psi_p * flywheel_speed)

    return ram_motion


def lever_radius_coefficient_of(radius: float, pivot_distance: float, cos_crank: float,
                                sin_crank: float) -> float:
    """
    Return d(psi)/d(r) (rad/m): h cos(phi_c) / |pin - O3|^2, the crank's direction given.

    The stroke screw's force is the lever torque times this (stroke_efforts.
    lever_radius_coefficient at a flywheel angle; the speed drive's sample).
    """
    return pivot_distance * cos_crank / (radius * radius + pivot_distance * pivot_distance
                                         + 2.0 * radius * pivot_distance * sin_crank)


# What lean_speed_drive_sample returns, in order: the published joints' motion, the chain's
# Efforts fields, the stroke screw's force.
SPEED_DRIVE_SAMPLE_FIELDS = (
    'flywheel_angle', 'flywheel_speed', 'lever_angle', 'lever_speed', 'ram_position',
    'ram_velocity', 'input_torque', 'flywheel_torque', 'lever_torque', 'ram_force',
    'offset_force', 'crank_radius_force')


def lean_speed_drive_sample(constants: LeanConstants, cutting_force: float,
                            cutting_length: float, ram_friction: float, offset: float,
                            angle: float, speed: float, acceleration: float,
                            offset_rate: float) -> Tuple[float, ...]:
    """
    Return a speed-drive sample with the stroke still: motion, efforts, screw force.

    SPEED_DRIVE_SAMPLE_FIELDS, from the input's angle, speed and acceleration and the
    offset and its rate (the offset's acceleration zero), under the loads given (N, m, N).
    The operations of mechanism_state.state (positions and speeds: no powers, which a
    compiled form would turn into products), then dynamics.one_sample_ram_load,
    ``lean_efforts_of`` and ``lever_radius_coefficient_of`` on one sample, in their order,
    so it gives their numbers bit for bit (a test holds it to them);
    qrm_ros.core.dynamics.drive_kernel compiles it for the node's tick.
    """
    r1, r, h, height, phase = constants[0], constants[1], constants[2], constants[3], constants[4]
    # state(): the coupling (the first slot's rate), then the lever (the second's).
    cos_a, sin_a = math.cos(angle), math.sin(angle)
    flywheel_angle = angle + math.atan2(offset * cos_a, r1 + offset * sin_a)
    px = r1 * cos_a
    py = r1 * sin_a + offset
    vx = -r1 * sin_a * speed
    vy = r1 * cos_a * speed + offset_rate
    flywheel_speed = (px * vy - py * vx) / (px * px + py * py)
    crank_angle = flywheel_angle + phase
    cos_c, sin_c = math.cos(crank_angle), math.sin(crank_angle)
    lever_angle = math.atan2(r * cos_c, h + r * sin_c)
    px = r * cos_c
    py = r * sin_c + h
    vx = -r * sin_c * flywheel_speed
    vy = r * cos_c * flywheel_speed + 0.0
    lever_speed = -((px * vy - py * vx) / (px * px + py * py))
    tan_lever = r * cos_c / (h + r * sin_c)
    ram_position = height * tan_lever
    ram_velocity = height * lever_speed * (1.0 + tan_lever * tan_lever)
    load = one_sample_ram_load(cutting_force, cutting_length, ram_friction, ram_position,
                               ram_velocity)
    (input_torque, flywheel_torque, lever_torque, ram_force,
     offset_force) = lean_efforts_of(constants, offset, angle, speed, acceleration,
                                     offset_rate, load)
    screw_force = lever_torque * lever_radius_coefficient_of(r, h, cos_c, sin_c)
    return (flywheel_angle, flywheel_speed, lever_angle, lever_speed, ram_position,
            ram_velocity, input_torque, flywheel_torque, lever_torque, ram_force,
            offset_force, screw_force)
