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
Deterministic time stepping of the mechanism's driven states (no ROS).

Only three quantities are integrated: the input shaft angle (the integral of a speed that
ramps toward its command at a limited acceleration), the coupling offset and the ram stroke
(each moving toward its command at a limited rate; the crank radius follows the stroke in
closed form, core.stepping.stroke_adjustment). The profiles are piecewise linear in time, so each
step integrates them exactly (a ramp's integral is its trapezoid; an interval in which a ramp
reaches its command is split there). Everything else is the kinematics core's closed form at
the stamp, so the state is exact at every stamp whatever the spacing of the stamps.

The node and the tests share this class, and a recorded run can be replayed through it:

* stamps are integer nanoseconds (a ROS stamp's ``sec * 10**9 + nanosec``), so time
  differences are exact at any epoch (a float in seconds near today's Unix time only
  resolves 0.24 microseconds);
* a command (speed, offset, limits) takes effect from the stamp of the last step, so
  replaying means: apply each command that came between two published samples, then step
  to the later sample's stamp;
* the arithmetic is plain Python floats in a fixed order, so the same commands at the same
  stamps give bit-identical results.

The input angle is kept wrapped to [-pi, pi), removing whole turns with a two-part 2 pi, so
its absolute precision does not decay over long runs at high speed.
"""

import math
from typing import Optional, Tuple

from qrm_ros.core.common.checks import finite, positive
from qrm_ros.core.kinematics.geometry import check_offset, Geometry, MechanismState
from qrm_ros.core.kinematics.mechanism_state import state
from qrm_ros.core.numerics.ramps import ramp
from qrm_ros.core.stepping.stroke_adjustment import fixed_stroke, StrokeRamp
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

# ramp: from core.numerics.ramps
__all__ = ['checked_limits', 'ramp', 'ShaperStepper', 'wrap_angle']

# 2 pi split into the nearest double and the remainder. Measured, it makes no difference to
# long-run precision (bench/bench_angle_precision.py: ~2.5e-16 rad per revolution either
# way, from rounding each tick's increment); kept because the golden logs replay bit for bit
# with it.
_TWO_PI_HIGH = 2.0 * math.pi
_TWO_PI_LOW = 2.4492935982947064e-16
_BELOW_PI = math.nextafter(math.pi, 0.0)


def wrap_angle(angle: float) -> float:
    """Return angle minus whole turns, in [-pi, pi) (floats: [-math.pi, math.pi))."""
    turns = math.floor((angle + math.pi) / _TWO_PI_HIGH)
    if turns:
        angle = (angle - turns * _TWO_PI_HIGH) - turns * _TWO_PI_LOW
    # Rounding (and the double pi being 1.2e-16 short of pi) can leave the result a hair
    # outside the half-open interval; moving it back costs at most one last bit.
    if angle >= math.pi:
        angle = max((angle - _TWO_PI_HIGH) - _TWO_PI_LOW, -math.pi)
    elif angle < -math.pi:
        angle = min((angle + _TWO_PI_HIGH) + _TWO_PI_LOW, _BELOW_PI)
    return angle


def checked_limits(acceleration_limit: float, offset_rate_limit: float,
                   new_acceleration_limit: Optional[float] = None,
                   new_offset_rate_limit: Optional[float] = None) -> Tuple[float, float]:
    """
    Return the (input acceleration, offset rate) limits after a change (None keeps one).

    Both are checked before either is taken, so a refused change changes nothing.
    """
    if new_acceleration_limit is not None:
        acceleration_limit = positive('input_acceleration_limit', new_acceleration_limit,
                                      'rad/s^2')
    if new_offset_rate_limit is not None:
        offset_rate_limit = positive('offset_rate_limit', new_offset_rate_limit, 'm/s')
    return acceleration_limit, offset_rate_limit


class ShaperStepper:
    """
    Input angle, input speed, offset and stroke of the mechanism, stepped exactly.

    Rates reported at a stamp (input_acceleration, offset_rate, the stroke's) are the ones
    that apply from that stamp on, given the commands known then.

    Time going backwards (a simulated clock restarted) integrates nothing: the held state
    is returned at the new stamp, which becomes the new time base, and time_resets counts
    it. The same happens on the first step and after reset() or resync().
    """

    def __init__(self, geometry: Geometry, input_speed: float, offset: float,
                 input_acceleration_limit: float, offset_rate_limit: float,
                 stroke: Optional[StrokeRamp] = None) -> None:
        self._geometry = geometry
        # The ram stroke (the crank radius in force); without one, geometry's, held.
        self._stroke = stroke or fixed_stroke(geometry)
        self._acceleration_limit = positive('input_acceleration_limit',
                                            input_acceleration_limit, 'rad/s^2')
        self._offset_rate_limit = positive('offset_rate_limit', offset_rate_limit, 'm/s')
        self.time_resets = 0
        self.integration_cutoffs = 0  # exact in closed form: every stamp is reached
        self.reset(input_speed, offset)

    # Commands -----------------------------------------------------------------------------

    def set_speed_command(self, input_speed: float) -> None:
        """Command the input shaft speed (rad/s); reached at input_acceleration_limit."""
        self._speed_command = finite('input_speed', input_speed, 'rad/s')

    def set_offset_command(self, offset: float) -> None:
        """Command the coupling offset (m, |offset| < coupling_radius); moved at the limit."""
        self._offset_command = float(check_offset(self._geometry, offset))

    def set_stroke_command(self, stroke_length: float) -> None:
        """Command the ram stroke (m); the crank radius follows at the stroke's rate limit."""
        self._stroke.set_command(stroke_length)

    def set_limits(self, input_acceleration_limit: Optional[float] = None,
                   offset_rate_limit: Optional[float] = None) -> None:
        """Change either limit (rad/s^2, m/s; > 0); None keeps the present value."""
        self._acceleration_limit, self._offset_rate_limit = checked_limits(
            self._acceleration_limit, self._offset_rate_limit, input_acceleration_limit,
            offset_rate_limit)

    def reset(self, input_speed: float, offset: float, *,
              stroke_length: Optional[float] = None) -> None:
        """
        Input angle to zero; speed, offset and stroke (state and command) set at once.

        No ramp; stroke_length None: the stroke left as it is. The next step starts a new
        time base (it returns this state at its stamp).
        """
        input_speed = finite('input_speed', input_speed, 'rad/s')
        offset = float(check_offset(self._geometry, offset))
        self._stroke.reset(stroke_length)
        self._input_angle = 0.0
        self._input_speed = self._speed_command = input_speed
        self._offset = self._offset_command = offset
        self._stamp_ns: Optional[int] = None

    def restore(self, stamp_ns: int, input_angle: float, input_speed: float,
                offset: float, *, stroke_length: Optional[float] = None) -> None:
        """
        Take a recorded state as the present one, at its stamp (to replay a logged run).

        Commands equal the state until set; stepping on from here repeats, bit for bit, what
        the stepper that produced the state did, given the same commands at the same stamps.
        """
        input_angle = finite('input_angle', input_angle, 'rad')
        self.reset(input_speed, offset, stroke_length=stroke_length)
        self._input_angle = wrap_angle(input_angle)
        self._stamp_ns = int(stamp_ns)

    def resync(self) -> None:
        """Hold the state: the next step starts a new time base (used after a pause)."""
        self._stamp_ns = None

    # Stepping -----------------------------------------------------------------------------

    def integrate_to(self, stamp_ns: int) -> None:
        """Advance the input angle, speed and offset to stamp_ns (int nanoseconds)."""
        stamp_ns = int(stamp_ns)
        previous = self._stamp_ns
        self._stamp_ns = stamp_ns
        if previous is None or stamp_ns == previous:
            return
        if stamp_ns < previous:
            self.time_resets += 1
            return
        duration = (stamp_ns - previous) / NANOSECONDS_PER_SECOND
        speed, angle_change = ramp(self._input_speed, self._speed_command,
                                   self._acceleration_limit, duration)
        offset, _ = ramp(self._offset, self._offset_command, self._offset_rate_limit,
                         duration)
        self._input_speed = speed
        self._offset = offset
        self._stroke.advance(duration)
        self._input_angle = wrap_angle(self._input_angle + angle_change)

    def mechanism_state(self) -> MechanismState:
        """Return the kinematics core's exact state (MechanismState) at the present stamp."""
        return state(self._stroke.geometry, self._offset, self._input_angle,
                     self._input_speed, self.input_acceleration, self.offset_rate,
                     *self._stroke.crank_radius_rates())

    def advance_to(self, stamp_ns: int) -> MechanismState:
        """Step to stamp_ns (int nanoseconds) and return the mechanism's state there."""
        self.integrate_to(stamp_ns)
        return self.mechanism_state()

    # State --------------------------------------------------------------------------------

    @property
    def geometry(self) -> Geometry:
        """The geometry with the crank radius in force."""
        return self._stroke.geometry

    @property
    def stroke(self) -> StrokeRamp:
        """The ram stroke in force, its command and rate limit, the crank radius."""
        return self._stroke

    @property
    def stamp_ns(self) -> Optional[int]:
        """Stamp of the last step (int ns), or None when the next step starts a time base."""
        return self._stamp_ns

    @property
    def input_angle(self) -> float:
        """Input shaft angle, rad, in [-pi, pi)."""
        return self._input_angle

    @property
    def input_speed(self) -> float:
        """Input shaft speed, rad/s."""
        return self._input_speed

    @property
    def input_acceleration(self) -> float:
        """Input shaft acceleration from the present stamp on, rad/s^2."""
        gap = self._speed_command - self._input_speed
        return math.copysign(self._acceleration_limit, gap) if gap else 0.0

    @property
    def offset(self) -> float:
        """Coupling offset in force, m."""
        return self._offset

    @property
    def offset_rate(self) -> float:
        """Rate of the coupling offset from the present stamp on, m/s."""
        gap = self._offset_command - self._offset
        return math.copysign(self._offset_rate_limit, gap) if gap else 0.0

    @property
    def speed_command(self) -> float:
        return self._speed_command

    @property
    def offset_command(self) -> float:
        return self._offset_command

    @property
    def input_acceleration_limit(self) -> float:
        return self._acceleration_limit

    @property
    def offset_rate_limit(self) -> float:
        return self._offset_rate_limit
