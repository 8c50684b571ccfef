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
One segment of the motor stepper's integration: what it follows and its functions.

A segment runs from one switch of the right-hand side to the next (stroke reversal, tool
entering or leaving the workpiece, motor reaching or leaving its torque limit, input speed
through zero, a ramp ending, any command). ``SegmentPlan`` holds what it follows: the
commands and their limits, the ramps toward them from the segment's start, and the mode
chosen there (the ram's direction, in the work or not, the motor saturated or not, the
shaft's spin, the ram load). ``segment_functions`` makes the segment's right-hand side and
switching functions from it, closures over its constants.
"""

import bisect
import math
from typing import Callable, List, NamedTuple, Optional, Tuple

from qrm_ros.core.dynamics.chain import Chain
from qrm_ros.core.kinematics.geometry import TWO_PI
from qrm_ros.core.dynamics.lean_chain import lean_acceleration_of
from qrm_ros.core.motor.motor_equation import EquationOfMotion, sign
from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.motor.motor_stroke import moving_radius_motion, StrokeSegment
from qrm_ros.core.stepping.stepping import ramp, wrap_angle

__all__ = ['DIRECTION', 'SATURATION', 'Segment', 'segment_functions', 'SegmentFunctions',
           'SegmentPlan', 'SPIN', 'SWITCH_ANGLE_MARGIN', 'WORK']

# A step whose sampled angles all stay this far (rad) from the ram's reversals and the
# workpiece's edges (closed form, offset held) has no sign change of those two switching
# functions at its samples, so they are not evaluated there: their computed signs are
# exact beyond about 1e-8 rad (sqrt(eps): a workpiece as long as the stroke touches zero
# at a reversal).
SWITCH_ANGLE_MARGIN = 1e-6
# A ram reversal landed on with the input slower than this (rad/s) is the shaft stopping.
_STOP_SPEED = 1e-9
# Why a segment of the integration ended (what changed at the restart): the index of its
# switching function among switching's values.
DIRECTION, WORK, SATURATION, SPIN = range(4)


class SegmentPlan:
    """
    The present segment's commands, limits, ramps and mode (the stepper's, changed by it).

    The reference and the offset ramp from their values at the segment's start toward their
    commands at their limits; reference_end and offset_end say when they get there (-inf:
    no ramp). The ram stroke ramps likewise (``stroke``, a StrokeSegment; without one, a
    stroke that never moves).
    """

    def __init__(self, acceleration_limit: float, offset_rate_limit: float,
                 stroke: Optional[StrokeSegment] = None) -> None:
        self.acceleration_limit = acceleration_limit  # rad/s^2
        self.offset_rate_limit = offset_rate_limit  # m/s
        self.speed_command = self.offset_command = 0.0
        self.start = 0.0  # s
        self.reference = self.offset = 0.0  # at the segment's start: rad/s, m
        self.reference_end = self.offset_end = -math.inf  # s
        self.offset_rate = 0.0  # m/s
        self.direction = 1  # the ram's, +-1
        self.in_work = False
        self.half_work = 0.0  # m: half the workpiece's length
        self.spin = 0  # the input speed's sign
        self.saturation = 0  # +-1: the motor at +-max_torque
        self.load = 0.0  # N along +x
        self.stroke = stroke or StrokeSegment(1.0, 1.0)  # the ram stroke's ramp

    def reset(self, speed: float, offset: float) -> None:
        """Speed and offset (commands and the segment's start) set at once; no ramp, at rest."""
        self.speed_command = self.reference = speed
        self.offset_command = self.offset = offset
        self.start = 0.0
        self.reference_end = self.offset_end = -math.inf
        self.offset_rate = 0.0
        self.spin = 0
        self.load = 0.0
        self.saturation = 0

    def reference_at(self, time: Optional[float]) -> float:
        """Return the motor's speed reference (rad/s) at time (s; None: the segment's start)."""
        if time is None:
            return self.reference
        if time >= self.reference_end:
            return self.speed_command
        return ramp(self.reference, self.speed_command, self.acceleration_limit,
                    time - self.start)[0]

    def offset_at(self, time: Optional[float]) -> float:
        """Return the offset (m) at time (s; None: the segment's start; held at rest)."""
        if time is None or self.spin == 0:
            return self.offset  # held at rest
        if time >= self.offset_end:
            return self.offset_command
        return ramp(self.offset, self.offset_command, self.offset_rate_limit,
                    time - self.start)[0]

    def start_ramps(self, time: float, reference: float, offset: float) -> None:
        """Start the segment's ramps at time (s) from the reference and offset there."""
        self.start, self.reference, self.offset = time, reference, offset
        # When (s) the reference and the offset reach their commands: kinks to stop at.
        gap = self.speed_command - reference
        self.reference_end = time + abs(gap) / self.acceleration_limit if gap else -math.inf
        gap = self.offset_command - offset
        self.offset_end = time + abs(gap) / self.offset_rate_limit if gap else -math.inf

    def begin(self, equation: EquationOfMotion, time: float, angle: float, speed: float,
              reference: float, offset: float, trigger: Optional[int],
              stroke: Optional[float] = None) -> Tuple[float, float, Optional[str]]:
        """
        Begin a segment at time (s) from this state; return (angle, speed, stall reason).

        The ramps start from the reference, offset and stroke (m; None: the segment's
        stroke at time) there; the angle comes back wrapped, the speed after the offset's
        and the crank radius' rate jumps (or 0.0: the shaft stopped); the mode is chosen
        from the state (choose_mode). trigger is the switch that ended the last segment
        (None: any other restart). equation is the one at the stroke there.
        """
        old_rate = self.offset_rate
        gap = self.offset_command - offset
        rate = math.copysign(self.offset_rate_limit, gap) if gap else 0.0
        self.start_ramps(time, reference, offset)
        ram_stroke = self.stroke
        if stroke is None:
            stroke = ram_stroke.at(time)
        old_radius_rate = ram_stroke.radius_motion(stroke, ram_stroke.rate_before(time))[1]
        _, radius_rate, radius_acceleration = ram_stroke.radius_motion(
            stroke, ram_stroke.begin(time, stroke))
        angle = wrap_angle(angle)
        if rate != old_rate or radius_rate != old_radius_rate:
            speed = equation.speed_after_rate_jump(offset, angle, speed, old_rate, rate,
                                                   old_radius_rate, radius_rate)
        self.offset_rate = rate
        chain = equation.chain(offset, angle, speed, rate, radius_rate, radius_acceleration)
        self.half_work = 0.5 * equation.loads.cutting_length
        if trigger is not None and self.spin and (
                sign(speed) != self.spin
                or (trigger == DIRECTION and abs(speed) <= _STOP_SPEED)):
            # Another switch landed where the speed is through zero (the load's reversal
            # and the shaft's coincide when the shaft stops): that is a stop first.
            trigger = SPIN
        if trigger == SPIN:
            speed = 0.0
            chain = equation.chain(offset, angle, speed, rate, radius_rate,
                                   radius_acceleration)
        return angle, speed, self.choose_mode(equation, chain, angle, speed, reference, trigger)

    def choose_mode(self, equation: EquationOfMotion, chain: Chain, angle: float, speed: float,
                    reference: float, trigger: Optional[int]) -> Optional[str]:
        """
        Choose the mode from the state at the segment's start; return why it stalls, if so.

        chain is the chain there, trigger the switch that ended the last segment (None: any
        other restart): that switch's mode flips, the others are read off the state.
        """
        velocity = chain.ram_velocity
        if trigger == DIRECTION:
            self.direction = -self.direction
        else:
            self.direction = sign(velocity) or sign(chain.ram_lever_arm * speed) or 1
        if trigger == WORK:
            self.in_work = not self.in_work
        else:
            self.in_work = abs(chain.ram_position) <= self.half_work
        stall_reason = None
        self.spin = sign(speed)
        if self.spin == 0:
            self.spin, self.direction, stall_reason = equation.at_rest(
                chain, angle, reference, self.speed_command, velocity, self.in_work,
                self.direction)
        if trigger == SATURATION:
            assert equation.motor is not None  # only a motor saturates
            demand = equation.motor.speed_stiffness * (reference - speed)
            self.load = equation.ram_load(self.direction, self.in_work)
            # At the switch the demand may still read 0 (the band is within the speed's
            # round-off): it leaves the band the way it is moving, k (reference rate - a).
            ramping = math.copysign(self.acceleration_limit, self.speed_command - reference)
            leaving = sign((ramping if self.reference_end > self.start else 0.0)
                           - equation.acceleration(chain, demand, self.load))
            self.saturation = 0 if self.saturation else (sign(demand) or leaving)
        else:
            self.saturation = equation.saturation_of(reference, speed)
        self.load = equation.ram_load(self.direction, self.in_work)
        return stall_reason

    def breakpoint(self, time: float) -> float:
        """Next time (s) a ramp ends after time, where the right-hand side has a kink."""
        ends = [end for end in (self.reference_end, self.offset_end, self.stroke.end)
                if end > time]
        return min(ends, default=math.inf)


class SegmentFunctions(NamedTuple):
    """A segment's right-hand side, acceleration and switching functions (closures)."""

    rhs: Callable  # (time, [angle, speed]) -> [speed, acceleration], for DOP853
    acceleration: Callable[[float, float, float], float]  # (time, angle, speed) -> rad/s^2
    switching: Callable[..., List[float]]  # (time, angle, speed, ram=True) -> values > 0
    clear: Callable[[float, float], bool]  # (low, high) angles clear of the load's switches
    motor_holds: Callable[[float, float, float], bool]  # (start, low, high) speeds


class Segment(NamedTuple):
    """A stepper's segment in force: what it follows, its functions, its equation of motion."""

    plan: SegmentPlan
    functions: Optional[SegmentFunctions]  # None until the shaft first moves
    equation: EquationOfMotion


def segment_functions(plan: SegmentPlan, equation: EquationOfMotion) -> SegmentFunctions:
    """
    Return the present segment's right-hand side, acceleration and switching functions.

    acceleration(time, angle, speed) is the input's (rad/s^2) from the equation of motion;
    switching(time, angle, speed) the values that stay > 0 while the segment's mode holds
    (one per switch kind). Closures over the segment's constants: the right-hand side runs
    about 16 times a solver step, the switch checks 6 times. The compiled acceleration is
    taken if it has loaded, else the Python form (the same numbers).
    """
    compiled = COMPILED_DRIVE_KERNEL.module
    kernel, constants = ((lean_acceleration_of, equation.lean_constants)
                         if compiled is None else
                         (compiled.lean_acceleration, equation.lean_array))
    ram_motion = equation.ram_motion
    motor = equation.motor
    command, reference_end, segment_reference = (plan.speed_command, plan.reference_end,
                                                 plan.reference)
    target, offset_end, segment_offset = (plan.offset_command, plan.offset_end, plan.offset)
    acceleration_limit, rate_limit = plan.acceleration_limit, plan.offset_rate_limit
    start, rate, load, saturation = plan.start, plan.offset_rate, plan.load, plan.saturation
    stiffness, limit = (0.0, 0.0) if motor is None else (motor.speed_stiffness,
                                                         motor.max_torque)
    direction, spin, half_work = plan.direction, plan.spin, plan.half_work
    # The stroke screw moving the crank pin: the chain written out at r(t) (motor_stroke).
    moving = plan.stroke.moving
    motion_at = (moving_radius_motion(plan.stroke, equation.lean_constants, rate, load)
                 if moving else None)
    switch_angles = (equation.switch_angles(segment_offset) if spin and rate == 0.0
                     and not moving else None)
    work_sign = 1 if plan.in_work else -1
    cutting = equation.loads.cutting_force > 0.0

    def reference_at(time):  # ramping (the callers check time < reference_end themselves)
        return ramp(segment_reference, command, acceleration_limit, time - start)[0]

    def offset_at(time):  # ramping (the callers check time < offset_end themselves)
        return ramp(segment_offset, target, rate_limit, time - start)[0]

    held_torque = saturation * limit if saturation else 0.0  # saturated, or no motor
    free = motor is not None and not saturation  # the torque follows the speed law

    def acceleration(time, angle, speed):
        if free:
            reference = command if time >= reference_end else reference_at(time)
            torque = stiffness * (reference - speed)
        else:
            torque = held_torque
        offset = target if time >= offset_end else offset_at(time)
        if motion_at is not None:  # the crank radius moves: M theta'' = T_m - b (r', r'')
            return motion_at(time, offset, angle, speed, torque)[0]
        return kernel(constants, offset, angle, speed, rate, torque, load)

    # The solver's times are never before the segment's start: with the ramps ended by
    # then, the reference is the command and the offset its target throughout, and the
    # right-hand side is acceleration's steady branch, written out.
    if max(reference_end, offset_end, plan.stroke.end) > start:
        def rhs(time, y):
            """Right-hand side for DOP853 (y: the state as a list of floats)."""
            angle, speed = y
            return [speed, acceleration(float(time), angle, speed)]
    elif free:
        def rhs(time, y):
            angle, speed = y
            return [speed, kernel(constants, target, angle, speed, rate,
                                  stiffness * (command - speed), load)]
    else:
        def rhs(time, y):
            angle, speed = y
            return [speed, kernel(constants, target, angle, speed, rate, held_torque,
                                  load)]

    def switching(time, angle, speed, ram=True):
        """ram=False: 1.0 for the ram's two (a step clear of the load's switches)."""
        if motor is None:
            torque_margin = 1.0
        else:
            reference = command if time >= reference_end else reference_at(time)
            demand = stiffness * (reference - speed)
            torque_margin = (limit - abs(demand) if saturation == 0
                             else saturation * demand - limit)
        if not ram:
            return [1.0, 1.0, torque_margin, spin * speed]
        offset = target if time >= offset_end else offset_at(time)
        if motion_at is None:
            position, velocity = ram_motion(offset, angle, speed, rate)
        else:
            _, position, velocity = motion_at(time, offset, angle, speed, 0.0)
        return [direction * velocity,
                (half_work - abs(position)) * work_sign if cutting else 1.0,
                torque_margin, spin * speed]

    def clear(low, high):
        """Say whether the angles low..high (rad) keep the margin from the load's switches."""
        if switch_angles is None:
            return False
        width = high - low + 2.0 * SWITCH_ANGLE_MARGIN
        low = (low - SWITCH_ANGLE_MARGIN) % TWO_PI
        index = bisect.bisect_left(switch_angles, low)
        following = (switch_angles[index] if index < len(switch_angles)
                     else switch_angles[0] + TWO_PI)  # the next switch up from low
        return following - low > width

    def motor_holds(start, low, high):
        """
        Say whether the motor's switching function is > 0 at all speeds low..high (rad/s).

        From start (s) on with the reference at its command: the function is then
        monotonic in the speed, in floating point too, so its ends bound it.
        """
        if motor is None:
            return True
        if start < reference_end:
            return False
        for speed in (low, high):
            demand = stiffness * (command - speed)
            if not (limit - abs(demand) if saturation == 0
                    else saturation * demand - limit) > 0.0:
                return False
        return True

    return SegmentFunctions(rhs, acceleration, switching, clear, motor_holds)
