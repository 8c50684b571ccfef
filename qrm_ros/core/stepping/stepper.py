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
The interface the node's steppers offer it, stated once: ``Stepper``.

Two classes step the mechanism between stamps: ``stepping.ShaperStepper`` (the ideal speed
drive: the speed ramps to its command) and ``motor_stepper.MotorStepper`` (the motor drive:
the speed is a state of the equation of motion). The node (qrm_ros.node.shaper_sim.shaper_sim)
holds either and calls the same members on it; the motor stepper offers more (efforts, stall,
motor torque), which the node asks of it by name.
"""

from typing import Optional, Protocol, runtime_checkable

from qrm_ros.core.kinematics.geometry import Geometry, MechanismState
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp

__all__ = ['Stepper']


@runtime_checkable
class Stepper(Protocol):
    """
    Input angle, input speed and offset of the mechanism, stepped between integer-ns stamps.

    Commands take effect from the stamp of the last step. Time going backwards integrates
    nothing: the held state is taken at the new stamp, which becomes the new time base, and
    time_resets counts it; the same happens on the first step and after reset() or resync().
    """

    time_resets: int
    # Steps that could not be integrated to their stamp within a bounded effort: the state
    # reached was held and a new time base started there (always 0 for an exact stepper).
    integration_cutoffs: int

    def set_speed_command(self, input_speed: float) -> None:
        """Command the input speed (rad/s)."""

    def set_offset_command(self, offset: float) -> None:
        """Command the coupling offset (m, |offset| < coupling_radius)."""

    def set_stroke_command(self, stroke_length: float) -> None:
        """Command the ram stroke (m); the crank radius follows at the stroke's rate limit."""

    def set_limits(self, input_acceleration_limit: Optional[float] = None,
                   offset_rate_limit: Optional[float] = None) -> None:
        """Change either limit (rad/s^2, m/s; > 0); None keeps the present value."""

    def reset(self, input_speed: float, offset: float, *,
              stroke_length: Optional[float] = None) -> None:
        """Input angle to zero, speed, offset and stroke set at once; a new time base next."""

    def restore(self, stamp_ns: int, input_angle: float, input_speed: float,
                offset: float, *, stroke_length: Optional[float] = None) -> None:
        """Take a recorded state as the present one, at its stamp (to replay a logged run)."""

    def resync(self) -> None:
        """Hold the state: the next step starts a new time base (used after a pause)."""

    def integrate_to(self, stamp_ns: int) -> None:
        """Advance the state to stamp_ns (int nanoseconds)."""

    def mechanism_state(self) -> MechanismState:
        """Return the kinematics core's exact state at the present stamp."""

    def advance_to(self, stamp_ns: int) -> MechanismState:
        """Step to stamp_ns (int nanoseconds) and return the mechanism's state there."""

    @property
    def geometry(self) -> Geometry:
        """The mechanism's geometry, with the crank radius in force."""

    @property
    def stroke(self) -> StrokeRamp:
        """The ram stroke in force, its command and rate limit, the crank radius."""

    @property
    def stamp_ns(self) -> Optional[int]:
        """Stamp of the last step (int ns), or None when the next step starts a time base."""

    @property
    def input_angle(self) -> float:
        """Input shaft angle, rad, in [-pi, pi)."""

    @property
    def input_speed(self) -> float:
        """Input shaft speed, rad/s."""

    @property
    def input_acceleration(self) -> float:
        """Input shaft acceleration at the present stamp, rad/s^2."""

    @property
    def offset(self) -> float:
        """Coupling offset in force, m."""

    @property
    def offset_rate(self) -> float:
        """Rate of the coupling offset from the present stamp on, m/s."""

    @property
    def speed_command(self) -> float:
        """The commanded input speed, rad/s."""

    @property
    def offset_command(self) -> float:
        """The commanded coupling offset, m."""

    @property
    def input_acceleration_limit(self) -> float:
        """The speed command's ramp rate, rad/s^2."""

    @property
    def offset_rate_limit(self) -> float:
        """The offset's rate toward its command, m/s."""
