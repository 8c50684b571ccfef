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
What the shaper_sim node commands from its parameters: the stroke, and the offset.

The offset follows coupling_offset by hand, or one hold: the cutting speed held at the
speed command (cutting_speed_target) or the time ratio held at the stroke
(time_ratio_target); the rules let at most one be set. Each is recomputed when what it
depends on changes, and goes through the offset's rate limit. A mixin of ShaperSimNode.
"""

from typing import Any, Dict

from qrm_ros.core.design.cutting_speed_hold import hold_offset
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp
from qrm_ros.core.design.time_ratio_hold import hold_time_ratio
from qrm_ros.node.shaper_sim.shaper_diagnostics import cutting_speed_status, time_ratio_status

__all__ = ['HeldFigures']


class HeldFigures:
    """The stroke and offset commands of the node (ShaperSimNode's attributes in use)."""

    _values: Dict[str, Any]
    _geometry: Geometry
    _stroke: StrokeRamp
    _stepper: Any
    _hold: Any
    _diagnostics_publisher: Any

    @property
    def stroke_command(self) -> float:
        """The ram stroke commanded, m: stroke_length, or crank_radius's when it is 0."""
        return self._values['stroke_length'] or float(self._geometry.ram_stroke)

    @property
    def stroke_in_force(self) -> float:
        return self._stroke.stroke

    @property
    def stroke_moving(self) -> bool:
        return self._stroke.stroke != self._stroke.command

    def command_stroke(self):
        """Command the stroke_length in force; a held ratio or speed follows it."""
        self._stepper.set_stroke_command(self.stroke_command)
        if self._values['cutting_speed_target'] or self._values['time_ratio_target']:
            self.command_offset()

    def command_offset(self):
        """
        Command the offset: coupling_offset by hand, or the held cutting speed's or ratio's.

        While cutting_speed_target is set, the offset that gives it at the speed command in
        force; while time_ratio_target is set, the one that gives it at the commanded stroke
        (the nearest reachable one, with a WARN, when a speed or stroke change has put the
        target out of reach).
        """
        values = self._values
        target = values['cutting_speed_target']
        ratio = values['time_ratio_target']
        if not (target or ratio):
            self._hold = None
            self._stepper.set_offset_command(values['coupling_offset'])
            return
        # The holds work at the commanded stroke: the offset and the stroke arrive together.
        geometry = self._stroke.geometry_at(self._stroke.command)
        if ratio:
            answer = hold_time_ratio(geometry, ratio)
        else:
            answer = hold_offset(geometry, self._stepper.speed_command, target,
                                 values['cutting_speed_definition'])
        self._stepper.set_offset_command(answer.offset)
        if answer.problem and (self._hold is None or self._hold.problem != answer.problem):
            self.get_logger().warning(answer.problem)
        self._hold = answer
        stamp = self.get_clock().now().to_msg()
        self._diagnostics_publisher.publish(
            time_ratio_status(values, answer, geometry, stamp) if ratio
            else cutting_speed_status(values, answer, stamp))
