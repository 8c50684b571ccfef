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
The motor drive while the stroke screw moves the crank pin: the crank radius r(t).

The stroke moves toward its command at a constant rate, so within a segment the crank
radius is a prescribed motion r(t) with its rate and acceleration in closed form
(stroke_adjustment.crank_radius_motion). The input's equation of motion then gains the
terms in r' and r'' (doc/dynamics.md): M theta'' = T_m - b, with b the chain's input torque
at zero input acceleration at the radius r(t), carrying r' and r''. The lean chain's
constants hold one radius, so such a segment takes the chain's operations written out with
the radius as an argument (``moving_radius_motion_of``, plain floats); once the stroke has
arrived, the next segment takes the lean (and compiled) forms at the new radius again.

``StrokeSegment`` is the stroke's part of a segment's plan: where the stroke starts, its
command, rate limit and the ramp's end. ``moving_radius_motion`` gives a segment's input
acceleration and ram motion at a time, the radius moving. ``MovingStroke`` is the motor
stepper's stroke: its command, the equation of motion at the radius in force, the efforts
while it moves.
"""

import math
from typing import Any, Callable, Optional, Sequence, Tuple

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.dynamics.lean_chain import coupling_and_crank
from qrm_ros.core.motor.motor_equation import EquationOfMotion
from qrm_ros.core.numerics.ramps import ramp
from qrm_ros.core.stepping.stroke_adjustment import crank_radius_motion, StrokeRamp

__all__ = ['moving_radius_motion', 'moving_radius_motion_of', 'MovingStroke', 'StrokeSegment']


class StrokeSegment:
    """
    The ram stroke over one segment: it ramps from its value at the segment's start.

    pivot_distance and ram_height (m) turn a stroke into a crank radius; the stroke's
    command and rate limit are the StrokeRamp's when the segment starts.
    """

    def __init__(self, pivot_distance: float, ram_height: float) -> None:
        self.pivot_distance = pivot_distance
        self.ram_height = ram_height
        self.start = 0.0  # s
        self.stroke = self.command = 0.0  # m: at the segment's start, commanded
        self.rate_limit = 1.0  # m/s of stroke
        self.end = -math.inf  # s: when the stroke reaches its command (-inf: no ramp)
        self.rate = 0.0  # m/s of stroke, from the segment's start to end

    def take(self, command: float, rate_limit: float) -> None:
        """Take the stroke's command (m) and rate limit (m/s) for the next segment."""
        self.command, self.rate_limit = command, rate_limit

    def reset(self, stroke: float) -> None:
        """Stroke at rest at stroke (m), no ramp (a reset)."""
        self.stroke = self.command = stroke
        self.start, self.end, self.rate = 0.0, -math.inf, 0.0

    def at(self, time: Optional[float]) -> float:
        """Return the stroke (m) at time (s; None: the segment's start)."""
        if time is None:
            return self.stroke
        if time >= self.end:
            return self.command
        return ramp(self.stroke, self.command, self.rate_limit, time - self.start)[0]

    def rate_before(self, time: float) -> float:
        """Return the stroke's rate (m/s) just before time (s), in this segment."""
        return self.rate if time <= self.end else 0.0

    def radius_motion(self, stroke: float, rate: float) -> Tuple[float, float, float]:
        """Return (r m, r' m/s, r'' m/s^2) at a stroke (m) moving at rate (m/s)."""
        return crank_radius_motion(stroke, rate, self.pivot_distance, self.ram_height)

    def begin(self, time: float, stroke: float) -> float:
        """Start the segment's ramp at time (s) from stroke (m); return its rate, m/s."""
        self.start, self.stroke = time, stroke
        gap = self.command - stroke
        self.rate = math.copysign(self.rate_limit, gap) if gap else 0.0
        self.end = time + abs(gap) / self.rate_limit if gap else -math.inf
        return self.rate

    @property
    def moving(self) -> bool:
        """Say whether the stroke ramps in the segment (from its start on)."""
        return self.end > self.start


def moving_radius_motion_of(constants: Sequence[float], offset: float, angle: float,
                            speed: float, offset_rate: float, torque: float, load: float,
                            radius: float, radius_rate: float,
                            radius_acceleration: float) -> Tuple[float, float, float]:
    """
    Return (input acceleration rad/s^2, ram position m, ram velocity m/s), the radius moving.

    dynamics.evaluate_chain's operations at zero input and offset acceleration on plain
    floats, with the crank radius (m), its rate and acceleration given: its numbers to
    round-off (a test holds them together) at a fraction of its cost. constants are
    lean_chain.lean_constants' (those of the radius are not used).
    """
    (_, _, h, height, _, input_inertia, flywheel_inertia, lever_inertia, ram_mass,
     lever_weight, _, _, _, _, _, _, _, two_height, _) = constants
    r = radius
    phi_t, phi_d, phi_tt, phi_td, phi_dd, sin_c, cos_c, tan_l = coupling_and_crank(
        constants, radius, offset, angle)
    r_r, h_h = r * r, h * h
    m = r_r + h_h + 2.0 * r * h * sin_c
    m2 = m * m
    psi_p = -r * (r + h * sin_c) / m
    psi_pp = -r * h * cos_c * (h_h - r_r) / m2
    psi_r = h * cos_c / m
    psi_pr = -h * (sin_c * (r_r + h_h) + 2.0 * r * h) / m2
    psi_rr = -2.0 * h * cos_c * (r + h * sin_c) / m2
    sec2 = 1.0 + tan_l * tan_l
    x_p = height * sec2
    flywheel_speed = phi_t * speed + phi_d * offset_rate
    flywheel_acc = (phi_tt * (speed * speed) + 2.0 * phi_td * speed * offset_rate
                    + phi_dd * offset_rate * offset_rate)
    lever_speed = psi_p * flywheel_speed + psi_r * radius_rate
    lever_acc = (psi_p * flywheel_acc + psi_pp * flywheel_speed * flywheel_speed
                 + psi_r * radius_acceleration + 2.0 * psi_pr * flywheel_speed * radius_rate
                 + psi_rr * radius_rate * radius_rate)
    ram_force = ram_mass * (x_p * lever_acc + two_height * tan_l * sec2 * lever_speed
                            * lever_speed) - load
    lever_torque = (lever_inertia * lever_acc - lever_weight * tan_l / math.sqrt(sec2)
                    + ram_force * x_p)
    flywheel_torque = flywheel_inertia * flywheel_acc + lever_torque * psi_p
    inertia = input_inertia + phi_t * phi_t * (
        flywheel_inertia + psi_p * psi_p * (lever_inertia + ram_mass * x_p * x_p))
    return ((torque - flywheel_torque * phi_t) / inertia, height * tan_l,
            x_p * lever_speed)


def moving_radius_motion(stroke: StrokeSegment, constants: Sequence[float],
                         offset_rate: float,
                         load: float) -> Callable[..., Tuple[float, float, float]]:
    """
    Return motion_at(time, offset, angle, speed, torque): moving_radius_motion_of's triple.

    The crank radius is the stroke's at time (s), with its rate and acceleration; the ram
    load (N along +x) and the offset rate (m/s) are the segment's, the input torque (N m)
    the caller's.
    """
    h, height = stroke.pivot_distance, stroke.ram_height
    start, stroke_start, command = stroke.start, stroke.stroke, stroke.command
    rate, rate_limit, end = stroke.rate, stroke.rate_limit, stroke.end

    def motion_at(time, offset, angle, speed, torque):
        if time >= end:
            radius, radius_rate, radius_acceleration = crank_radius_motion(
                command, 0.0, h, height)
        else:
            radius, radius_rate, radius_acceleration = crank_radius_motion(
                ramp(stroke_start, command, rate_limit, time - start)[0], rate, h, height)
        return moving_radius_motion_of(constants, offset, angle, speed, offset_rate, torque,
                                       load, radius, radius_rate, radius_acceleration)

    return motion_at


class MovingStroke:
    """
    The motor stepper's ram stroke (MotorStepper inherits it): command, geometry, efforts.

    The StrokeRamp holds the stroke in force, its command and rate limit; the segment plan's
    StrokeSegment the ramp the integration follows, taken from it at each segment's start
    (a command or rate limit set on the StrokeRamp directly: at the next stamp, from the
    last one on).
    """

    _stroke: StrokeRamp
    _plan: Any  # motor_segment.SegmentPlan
    _geometry: Geometry  # the present segment's: its equation's
    _equation: EquationOfMotion
    _changed: Callable[[Callable[[], None]], None]

    def set_stroke_command(self, stroke_length: float) -> None:
        """
        Command the ram stroke (m); the crank radius follows at the stroke's rate limit.

        Refused (KinematicsError, DynamicsError) if the slot cannot take it or the workpiece
        (cutting_length) is longer.
        """
        command = self._stroke.check(stroke_length)
        self._equation.loads.check_against(command)
        self._changed(lambda: self._stroke.set_command(command))

    def _stroke_changed(self) -> bool:
        """Say whether the StrokeRamp's command or rate limit differ from the segment's."""
        stroke, segment = self._stroke, self._plan.stroke
        return stroke.command != segment.command or stroke.rate_limit != segment.rate_limit

    def _reset_stroke(self, stroke_length: Optional[float]) -> None:
        """Stroke and command set at once, no ramp (None: as they are); see StrokeRamp.reset."""
        stroke, segment = self._stroke, self._plan.stroke
        stroke.reset(stroke_length)
        segment.reset(stroke.stroke)
        segment.take(stroke.command, stroke.rate_limit)
        self._take_geometry(stroke.geometry)

    def _take_geometry(self, geometry: Geometry) -> None:
        """Take the geometry of the crank radius in force (a new equation if it changed)."""
        if geometry is not self._geometry:
            old = self._equation
            self._equation = EquationOfMotion(geometry, old.mass, old.loads, old.motor,
                                              self._stroke.command)
            self._geometry = geometry

    def _radius_moved(self) -> bool:
        """Say whether the radius moves now, or is not the segment's (its lean forms')."""
        stroke = self._stroke
        return stroke.geometry is not self._geometry or bool(stroke.rate)

    def _moving_radius_efforts(self, offset: float, angle: float, speed: float,
                               acceleration: float, offset_rate: float,
                               load: float) -> dyn.Efforts:
        """Return the chain's efforts at the radius in force, with its rate and acceleration."""
        stroke, fixed = self._stroke, self._equation.fixed
        return dyn.evaluate_chain(fixed[0], fixed[1], float(stroke.crank_radius), *fixed[3:],
                                  offset, angle, speed, acceleration, offset_rate, 0.0, load,
                                  *stroke.crank_radius_rates()).efforts

    @property
    def stroke(self) -> StrokeRamp:
        """The ram stroke in force, its command and rate limit, the crank radius."""
        return self._stroke

    @property
    def geometry(self) -> Geometry:
        """The geometry with the crank radius in force."""
        return self._stroke.geometry
