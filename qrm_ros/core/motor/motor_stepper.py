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
The mechanism under a motor drive, stepped between stamps (pure numpy/scipy, no ROS).

``MotorStepper`` offers the node what ``stepping.ShaperStepper`` offers (the ``Stepper``
protocol, qrm_ros.core.stepping.stepper), with the input speed a state of the equation of motion.
Its parts: the equation of motion's ingredients (motor_equation), the present segment's
plan and functions (motor_segment), the solver within a segment (motor_integration) and the
compiled kernel loaded on a thread (drive_kernel_loading). ``simulate`` samples a run.

Integration: scipy's DOP853, restarted at every switch of the right-hand side (a new
segment, motor_segment): stroke reversal, tool entering or leaving the workpiece, motor
reaching or leaving its torque limit, input speed through zero, a ramp ending, any
command. A switch inside a step is found on the step's dense output with brentq, and the
step is cut there (motor_integration). Outputs at stamps come from dense output, so the
trajectory does not depend on the stamps asked for.

At zero input speed the stall rule (``EquationOfMotion.at_rest``) moves the shaft or holds
it (angle and offset still); held with a non-zero speed reference is a stall: ``stalled``
is True and ``stall_reason`` says why. The rule is re-checked at every step (loads, motor
and commands may change), and the shaft resumes as soon as it allows.
"""

import math
from typing import Callable, NamedTuple, Optional

import numpy as np

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.common.checks import finite, positive
from qrm_ros.core.kinematics.geometry import check_offset, Geometry, MechanismState
from qrm_ros.core.kinematics import state
from qrm_ros.core.dynamics.lean_chain import lean_efforts_of
from qrm_ros.core.motor.motor_equation import EquationOfMotion
from qrm_ros.core.motor.motor_integration import Observer, Piece, SegmentIntegration
from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.motor.motor_segment import (Segment, segment_functions, SegmentFunctions,
                                              SegmentPlan)
from qrm_ros.core.motor.motor_stroke import MovingStroke, StrokeSegment
from qrm_ros.core.stepping.stepping import checked_limits, wrap_angle
from qrm_ros.core.stepping.stroke_adjustment import fixed_stroke, StrokeRamp
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

__all__ = ['MAX_PIECES_PER_STAMP', 'MotorStepper', 'PlanViews', 'Simulation', 'simulate']

# Pieces of trajectory (solver steps) one integrate_to may make, about 0.5 s of computing: a
# clock that jumps far ahead, or a segment that keeps switching, cannot hold a tick (and the
# node's signal handling) for ever. Past it the state reached is held and a new time base
# starts at the stamp, as after a pause (integration_cutoffs counts them).
MAX_PIECES_PER_STAMP = 20_000


class PlanViews:
    """
    The motor stepper's commands, limits and stall as read from its segment plan.

    Read-only views that MotorStepper inherits (they need only the plan, the present time
    on it and the stall reason).
    """

    _plan: SegmentPlan
    _time: float
    _stall_reason: Optional[str]

    @property
    def ram_load(self) -> float:
        """F_ext on the ram in the present segment, N along +x."""
        return self._plan.load

    @property
    def stalled(self) -> bool:
        return self._stall_reason is not None

    @property
    def stall_reason(self) -> Optional[str]:
        """Why the shaft is held (str) while stalled, else None."""
        return self._stall_reason

    @property
    def offset(self) -> float:
        """Coupling offset in force, m."""
        return self._plan.offset_at(self._time)

    @property
    def offset_rate(self) -> float:
        """Rate of the coupling offset from the present stamp on, m/s."""
        return self._plan.offset_rate if self._plan.spin else 0.0

    @property
    def speed_reference(self) -> float:
        """The motor's speed reference now (the speed command after its ramp), rad/s."""
        return self._plan.reference_at(self._time)

    @property
    def speed_command(self) -> float:
        return self._plan.speed_command

    @property
    def offset_command(self) -> float:
        return self._plan.offset_command

    @property
    def input_acceleration_limit(self) -> float:
        return self._plan.acceleration_limit

    @property
    def offset_rate_limit(self) -> float:
        return self._plan.offset_rate_limit


class MotorStepper(MovingStroke, PlanViews):
    """
    The mechanism under a motor drive: the input speed is a state of the equation of motion.

    Interface and stamp rules as ``stepping.ShaperStepper``'s (integer-ns stamps, commands
    from the present stamp, time resets, wrapped angle); the speed command ramps into the
    motor's speed reference. An offset-rate or crank-radius-rate jump is an impulse on the
    offset or the crank pin only: the input's generalised momentum is kept, its speed jumps.
    Integration and the stall rule: the module's docstring. motor=None runs the shaft free
    (no motor torque). Stroke: motor_stroke.MovingStroke; it moves with the shaft at rest
    too (the screw is the operator's), the crank radius a prescribed motion.
    """

    def __init__(self, geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                 motor: Optional[dyn.MotorDrive], input_speed: float, offset: float,
                 input_acceleration_limit: float, offset_rate_limit: float,
                 stroke: Optional[StrokeRamp] = None) -> None:
        self._stroke = stroke = stroke or fixed_stroke(geometry)
        self._geometry = geometry = stroke.geometry
        self._plan = SegmentPlan(
            positive('input_acceleration_limit', input_acceleration_limit, 'rad/s^2'),
            positive('offset_rate_limit', offset_rate_limit, 'm/s'),
            StrokeSegment(float(geometry.pivot_distance), float(geometry.ram_height)))
        self._equation = EquationOfMotion(geometry, mass, loads, motor, stroke.command)
        COMPILED_DRIVE_KERNEL.start_loading()
        self.time_resets = self.integration_cutoffs = 0  # counted, for the node's status
        self._observer: Optional[Observer] = None
        self._functions: Optional[SegmentFunctions] = None
        self._acceleration_now: Optional[float] = None
        self.reset(input_speed, offset)

    # Commands -----------------------------------------------------------------------------

    def _changed(self, change: Callable[[], None]) -> None:
        """Apply change at the present stamp: the state there starts a new segment."""
        self._acceleration_now = None
        plan = self._plan
        if self._stamp_ns is None:
            change()
            if plan.spin:  # a held state (resync) reads the new settings as before
                self._functions = segment_functions(plan, self._equation)
            return
        angle, speed = self._angle, self._speed
        reference, offset = plan.reference_at(self._time), plan.offset_at(self._time)
        stroke = plan.stroke.at(self._time)
        change()
        self._start(self._time, angle, speed, reference, offset, None, stroke)

    def set_dynamics(self, mass: Optional[dyn.MassProperties] = None,
                     loads: Optional[dyn.Loads] = None,
                     motor: Optional[dyn.MotorDrive] = None) -> None:
        """Change masses, loads or motor (None keeps each) from the present stamp."""
        old = self._equation
        new = (old.mass if mass is None else mass, old.loads if loads is None else loads,
               old.motor if motor is None else motor)
        self._changed(lambda: setattr(self, '_equation', EquationOfMotion(
            self._geometry, *new, self._stroke.command)))

    def set_speed_command(self, input_speed: float) -> None:
        """Command the input speed (rad/s): the motor's reference ramps to it."""
        command = finite('input_speed', input_speed, 'rad/s')
        self._changed(lambda: setattr(self._plan, 'speed_command', command))

    def set_offset_command(self, offset: float) -> None:
        """Command the coupling offset (m, |offset| < coupling_radius); moved at the limit."""
        command = float(check_offset(self._geometry, offset))
        self._changed(lambda: setattr(self._plan, 'offset_command', command))

    def set_limits(self, input_acceleration_limit: Optional[float] = None,
                   offset_rate_limit: Optional[float] = None) -> None:
        """Change either limit (rad/s^2, m/s; > 0); None keeps the present value."""
        plan = self._plan
        limits = checked_limits(plan.acceleration_limit, plan.offset_rate_limit,
                                input_acceleration_limit, offset_rate_limit)

        def change() -> None:
            plan.acceleration_limit, plan.offset_rate_limit = limits
        self._changed(change)

    def reset(self, input_speed: float, offset: float, *,
              stroke_length: Optional[float] = None) -> None:
        """Input angle to zero; speed, reference and offset set at once; new time base next."""
        input_speed = finite('input_speed', input_speed, 'rad/s')
        offset = float(check_offset(self._geometry, offset))
        self._plan.reset(input_speed, offset)
        self._reset_stroke(stroke_length)
        self._angle, self._speed = 0.0, input_speed
        self._stamp_ns: Optional[int] = None
        self._base_ns = 0
        self._time = 0.0
        self._integration: Optional[SegmentIntegration] = None
        self._stall_reason: Optional[str] = None
        self._piece: Piece = (0.0, 0.0, None)  # type: ignore[assignment]  # none yet
        self._acceleration_now = None

    def restore(self, stamp_ns: int, input_angle: float, input_speed: float, offset: float,
                speed_reference: Optional[float] = None, *,
                stroke_length: Optional[float] = None) -> None:
        """
        Take a recorded state as the present one, at its stamp (to replay a logged run).

        The motor's speed reference (rad/s) is part of the state here; it and the speed
        command default to input_speed, as ShaperStepper's commands equal its state.
        """
        input_angle = finite('input_angle', input_angle, 'rad')
        reference = input_speed if speed_reference is None else speed_reference
        reference = finite('speed_reference', reference, 'rad/s')
        self.reset(input_speed, offset, stroke_length=stroke_length)
        self._plan.reference = self._plan.speed_command = reference
        self._angle = wrap_angle(input_angle)
        self._new_base(int(stamp_ns))

    def resync(self) -> None:
        """Hold the state: the next step starts a new time base (used after a pause)."""
        self._stamp_ns = None

    def set_observer(self, observer: Optional[Observer]) -> None:
        """Have observer(start, end, dense output) see every piece of trajectory as made."""
        self._observer = observer
        if self._integration is not None:
            self._integration.observer = observer

    # Segments -----------------------------------------------------------------------------

    def _new_base(self, stamp_ns: int) -> None:
        """Time base anew at stamp_ns; the ramps go on from now, not from the segment's start."""
        reference, offset = self._plan.reference_at(self._time), self._plan.offset_at(self._time)
        self._stamp_ns = self._base_ns = stamp_ns
        self._time = 0.0
        self._piece = (0.0, 0.0, None)  # type: ignore[assignment]
        self._start(0.0, self._angle, self._speed, reference, offset, None, self._stroke.stroke)

    def _start(self, time: float, angle: float, speed: float, reference: float, offset: float,
               trigger: Optional[int], stroke: float) -> None:
        """Start a segment at time with this state; choose its mode from the state."""
        self._acceleration_now = None
        # A command's restart from the present stamp replaces a switch found ahead, and the
        # pieces made ahead of the stamps.
        self._integration = None
        ram_stroke = self._stroke
        ram_stroke.move_to(stroke)
        self._take_geometry(ram_stroke.geometry)
        plan, equation = self._plan, self._equation
        plan.stroke.take(ram_stroke.command, ram_stroke.rate_limit)
        angle, speed, self._stall_reason = plan.begin(equation, time, angle, speed, reference,
                                                      offset, trigger, stroke)
        self._angle, self._speed = angle, speed
        if plan.spin == 0:
            self._piece = (time, math.inf, None)  # type: ignore[assignment]  # resting
            return
        # The segment's functions (not at rest: _start runs every tick while held).
        self._functions = segment_functions(plan, equation)
        self._integration = SegmentIntegration(self._functions, time, angle, speed,
                                               plan.breakpoint(time), plan.spin,
                                               self._observer)
        # The last piece stays valid up to here (a stamp just before the switch), no further.
        piece_start, _, at = self._piece
        self._piece = ((piece_start, time, at) if at is not None
                       else (time, time, None))  # type: ignore[assignment]

    def _extend(self) -> None:
        """Cover the next stretch of time: the segment's next piece, or the next segment."""
        integration = self._integration
        assert integration is not None  # moving: the segment is integrated
        piece = integration.next_piece()
        if piece is not None:
            self._piece = piece
            return
        # The stamps have passed the switch (or the ramp's end): its segment starts now (not
        # before, so that a stamp just before it reads the mode it is in: load, saturation,
        # direction).
        time, angle, speed, kind = integration.restart()
        self._start(time, angle, speed, self._plan.reference_at(time),
                    self._plan.offset_at(time), kind, self._plan.stroke.at(time))

    # Stepping -----------------------------------------------------------------------------

    def integrate_to(self, stamp_ns: int) -> None:
        """Advance the state to stamp_ns (int nanoseconds)."""
        stamp_ns = int(stamp_ns)
        previous = self._stamp_ns
        if previous is None:
            self._new_base(stamp_ns)
            return
        if stamp_ns == previous:
            return
        if stamp_ns < previous:
            self.time_resets += 1
            self._new_base(stamp_ns)
            return
        if self._stroke_changed():  # set on the StrokeRamp: from the last stamp on
            self._changed(lambda: None)
        self._stamp_ns = stamp_ns
        time = (stamp_ns - self._base_ns) / NANOSECONDS_PER_SECOND
        self._time = time
        self._acceleration_now = None
        plan = self._plan
        if plan.spin == 0:
            # At rest: the reference and the stroke may have ramped; re-check the stall rule.
            self._start(time, self._angle, 0.0, plan.reference_at(time), plan.offset, None,
                        plan.stroke.at(time))
            return
        pieces = 0
        while self._piece[1] < time:
            if pieces == MAX_PIECES_PER_STAMP:
                self._cut_off(stamp_ns)
                return
            self._extend()
            pieces += 1
            if plan.spin == 0 and self._piece[1] == math.inf:
                break
        self._stroke.move_to(plan.stroke.at(time))
        at = self._piece[2]
        if at is None:
            return  # resting, or the segment starts exactly here
        angle, speed = at(time)
        self._angle, self._speed = wrap_angle(angle), speed

    def _cut_off(self, stamp_ns: int) -> None:
        """Hold the state at the end of the last piece made; a new time base at stamp_ns."""
        end, at = self._piece[1], self._piece[2]
        if at is not None:
            angle, speed = at(end)
            self._angle, self._speed = wrap_angle(angle), speed
        self._stroke.move_to(self._plan.stroke.at(end))  # held where the state was reached
        self.integration_cutoffs += 1
        self._time = end
        self._new_base(stamp_ns)

    def mechanism_state(self) -> MechanismState:
        """Return the kinematics core's exact state (MechanismState) at the present stamp."""
        stroke = self._stroke
        return state(stroke.geometry, self.offset, self._angle, self._speed,
                     self.input_acceleration, self.offset_rate, *stroke.crank_radius_rates())

    def advance_to(self, stamp_ns: int) -> MechanismState:
        """Step to stamp_ns (int nanoseconds) and return the mechanism's state there."""
        self.integrate_to(stamp_ns)
        return self.mechanism_state()

    def efforts(self) -> dyn.Efforts:
        """``dynamics.Efforts`` at the present stamp (the motor's torque drives the input)."""
        arguments = (self.offset, self._angle, self._speed, self.input_acceleration,
                     self.offset_rate, self._plan.load)
        compiled = COMPILED_DRIVE_KERNEL.module
        if self._radius_moved():
            found = self._moving_radius_efforts(*arguments)
        elif compiled is None:
            found = dyn.Efforts(*lean_efforts_of(self._equation.lean_constants, *arguments))
        else:
            found = dyn.Efforts(*compiled.lean_efforts(self._equation.lean_array, *arguments))
        if self._plan.spin == 0:
            # Held at rest: the motor gives what its law gives there (within +-max_torque);
            # the rest of the holding torque is the ram's static friction, not the input's.
            return found._replace(input_torque=self.motor_torque)
        motor = self._equation.motor
        if motor is None:
            return found
        # Moving, the input's effort is the motor's torque; the clip keeps round-off of the
        # inverse dynamics (1e-15 N m) from showing past the limit.
        limit = motor.max_torque
        return found._replace(input_torque=min(max(found.input_torque, -limit), limit))

    @property
    def segment(self) -> Segment:
        """The segment in force: plan, functions, equation (exact figures between stamps)."""
        return Segment(self._plan, self._functions, self._equation)

    # State --------------------------------------------------------------------------------

    @property
    def stamp_ns(self) -> Optional[int]:
        """Stamp of the last step (int ns), or None when the next step starts a time base."""
        return self._stamp_ns

    @property
    def input_angle(self) -> float:
        """Input shaft angle, rad, in [-pi, pi)."""
        return self._angle

    @property
    def input_speed(self) -> float:
        """Input shaft speed, rad/s."""
        return self._speed

    @property
    def input_acceleration(self) -> float:
        """Input shaft acceleration at the present stamp from the equation of motion, rad/s^2."""
        if self._plan.spin == 0:
            return 0.0
        if self._acceleration_now is None:  # once per stamp: the state and efforts need it
            self._acceleration_now = self._functions.acceleration(  # type: ignore[union-attr]
                self._time, self._angle, self._speed)
        return self._acceleration_now

    @property
    def motor_torque(self) -> float:
        """Torque the motor applies to the input shaft now, N m."""
        return self._equation.applied_motor_torque(self._plan.reference_at(self._time),
                                                   self._speed)


class Simulation(NamedTuple):
    """Sampled trajectory of ``simulate`` (s, rad unwrapped, rad/s, rad/s^2, N m, ...)."""

    time: np.ndarray
    input_angle: np.ndarray
    input_speed: np.ndarray
    input_acceleration: np.ndarray
    motor_torque: np.ndarray
    efforts: dyn.Efforts
    stalled: np.ndarray


def simulate(geometry: Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
             motor: Optional[dyn.MotorDrive], offset: float, input_speed: float,
             duration: float, sample_rate: float, initial_speed: Optional[float] = None,
             input_acceleration_limit: float = 1e6,
             offset_rate_limit: float = 1.0) -> 'Simulation':
    """
    Run a MotorStepper from angle 0 and sample it at sample_rate (Hz) for duration (s).

    It starts at initial_speed (default input_speed, rad/s); the motor's reference ramps to
    input_speed.

    input_angle is unwrapped (it counts whole turns), for energy and work integrals.
    """
    duration = positive('duration', duration, 's')
    sample_rate = positive('sample_rate', sample_rate, 'Hz')
    input_speed = finite('input_speed', input_speed, 'rad/s')
    start_speed = input_speed if initial_speed is None else initial_speed
    stepper = MotorStepper(geometry, mass, loads, motor, start_speed, offset,
                           input_acceleration_limit, offset_rate_limit)
    stepper.integrate_to(0)
    stepper.set_speed_command(input_speed)
    count = int(math.floor(duration * sample_rate + 1e-9)) + 1
    step_ns = NANOSECONDS_PER_SECOND / sample_rate
    stamps = np.round(np.arange(count) * step_ns).astype(np.int64)
    rows = []
    for stamp in stamps:
        stepper.integrate_to(int(stamp))
        rows.append((stepper.input_angle, stepper.input_speed, stepper.input_acceleration,
                     stepper.motor_torque, *stepper.efforts(), stepper.stalled))
    table = np.array(rows, dtype=float)
    return Simulation(time=stamps / NANOSECONDS_PER_SECOND, input_angle=np.unwrap(table[:, 0]),
                      input_speed=table[:, 1], input_acceleration=table[:, 2],
                      motor_torque=table[:, 3], efforts=dyn.Efforts(*table[:, 4:9].T),
                      stalled=table[:, 9].astype(bool))
