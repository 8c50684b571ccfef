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
What the shaper_sim node says on /diagnostics, as DiagnosticArray messages.

Three statuses: a stroke pair's measured figures (with their theory and the cutting speed
held), the motor drive's stall, the cutting-speed hold. Their names are in
qrm_ros.core.common.names (the main job and the analysis read them back); their hardware_id is the
machine's (diagnostic_updater's convention: viewers show ``hardware_id: name``).
"""

import math
from typing import List, Mapping, Optional

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from qrm_ros.core.design.cutting_speed_hold import CUTTING_SPEED_FIGURES, HoldAnswer
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import (CUTTING_SPEED_STATUS, DRIVE_STATUS, MACHINE_NAME,
                                       STROKE_PAIR_STATUS, TIME_RATIO_STATUS)
from qrm_ros.core.measurement.stroke_monitor import PairReport
from qrm_ros.node.shaper_sim.linkage_markers import stamp_message
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher

__all__ = ['DriveStatusReport', 'STALL_REPEAT_NS', 'cutting_speed_status', 'stroke_pair_status',
           'time_ratio_status']

STALL_REPEAT_NS = 1_000_000_000  # a stall's ERROR status is repeated this often


def _array(status: DiagnosticStatus, stamp: Time) -> DiagnosticArray:
    message = DiagnosticArray(status=[status])
    message.header.stamp = stamp
    return message


def _shown_figure(value: float, spec: str = '.4f') -> str:
    """Show a figure as the status text does (4 decimals), or 'n/a' (never nan or inf)."""
    return format(value, spec) if math.isfinite(value) else 'n/a'


def stroke_pair_status(report: PairReport, effort_theory: List[KeyValue],
                       effort_theory_state: str, target: float,
                       definition: str, time_ratio_target: float = 0.0) -> DiagnosticArray:
    """
    Return a stroke pair's report as the DiagnosticArray to publish.

    effort_theory: the pair's effort theory as key-values, effort_theory_state a word on where
    it stands; target: the cutting speed held (0: none), in its definition;
    time_ratio_target: the time ratio held (0: none).
    """
    key_values = [KeyValue(key=key, value=repr(value))
                  for key, value in report.values().items() if math.isfinite(value)]
    key_values.append(KeyValue(key='offset_steady', value=str(report.offset_steady).lower()))
    key_values.append(KeyValue(key='input_speed_steady',
                               value=str(report.input_speed_steady).lower()))
    key_values.append(KeyValue(key='stroke_steady', value=str(report.stroke_steady).lower()))
    key_values.append(KeyValue(key='sampled_without_gap',
                               value=str(report.sampled_without_gap).lower()))
    if time_ratio_target:
        measured_ratio = report.measured['time_ratio']
        key_values += [
            KeyValue(key='time_ratio_target', value=repr(time_ratio_target)),
            KeyValue(key='time_ratio_error', value=repr(measured_ratio / time_ratio_target
                                                        - 1.0))]
    key_values += effort_theory
    key_values.append(KeyValue(key='effort_theory', value=effort_theory_state))
    if target:
        measured_speed = report.measured[CUTTING_SPEED_FIGURES[definition]]
        key_values += [
            KeyValue(key='cutting_speed_target', value=repr(target)),
            KeyValue(key='cutting_speed_definition', value=definition)]
        if math.isfinite(measured_speed):  # no figure rather than nan
            key_values += [
                KeyValue(key='cutting_speed_measured', value=repr(measured_speed)),
                KeyValue(key='cutting_speed_error', value=repr(measured_speed / target - 1.0))]
    measured = report.measured
    steady = ('steady' if report.steady else 'NOT steady (ratios mixed)'
              if report.sampled_without_gap else 'NOT steady (a gap in the samples)')
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK, name=STROKE_PAIR_STATUS, hardware_id=MACHINE_NAME,
        message=(f'TR {_shown_figure(measured["time_ratio"])}, SR '
                 f'{_shown_figure(measured["speed_ratio"])} (peak '
                 f'{_shown_figure(measured["peak_speed_ratio"])}) at offset '
                 f'{report.coupling_offset:.6g} m, {report.input_speed:.6g} rad/s, stroke '
                 f'{_shown_figure(report.stroke_length, ".6g")} m, {steady}'),
        values=key_values)
    return _array(status, stamp_message(report.stamp_ns))


def cutting_speed_status(values: Mapping[str, object], answer: HoldAnswer,
                         stamp: Time) -> DiagnosticArray:
    """Return the cutting-speed hold's state: OK when exact, else WARN (values: parameters)."""
    level = DiagnosticStatus.WARN if answer.problem else DiagnosticStatus.OK
    text = answer.problem or (
        f'holding {values["cutting_speed_definition"]} cutting speed '
        f'{values["cutting_speed_target"]:.6g} m/s with offset {answer.offset:.6g} m')
    key_values = [
        KeyValue(key='cutting_speed_target', value=repr(values['cutting_speed_target'])),
        KeyValue(key='cutting_speed_definition', value=values['cutting_speed_definition']),
        KeyValue(key='offset_command', value=repr(answer.offset)),
        KeyValue(key='reachable_min', value=repr(answer.reachable[0])),
        KeyValue(key='reachable_max', value=repr(answer.reachable[1]))]
    status = DiagnosticStatus(level=level, name=CUTTING_SPEED_STATUS,
                              hardware_id=MACHINE_NAME, message=text, values=key_values)
    return _array(status, stamp)


def time_ratio_status(values: Mapping[str, object], answer: HoldAnswer, geometry: Geometry,
                      stamp: Time) -> DiagnosticArray:
    """Return the time-ratio hold's state: OK when exact, else WARN (values: parameters)."""
    level = DiagnosticStatus.WARN if answer.problem else DiagnosticStatus.OK
    target = values['time_ratio_target']
    text = answer.problem or (
        f'holding time ratio {target:.6g} with offset {answer.offset:.6g} m at stroke '
        f'{geometry.ram_stroke:.6g} m')
    key_values = [
        KeyValue(key='time_ratio_target', value=repr(target)),
        KeyValue(key='offset_command', value=repr(answer.offset)),
        KeyValue(key='stroke_length', value=repr(float(geometry.ram_stroke))),
        KeyValue(key='crank_radius', value=repr(float(geometry.crank_radius))),
        KeyValue(key='reachable_min', value=repr(answer.reachable[0])),
        KeyValue(key='reachable_max', value=repr(answer.reachable[1]))]
    status = DiagnosticStatus(level=level, name=TIME_RATIO_STATUS,
                              hardware_id=MACHINE_NAME, message=text, values=key_values)
    return _array(status, stamp)


class DriveStatusReport:
    """
    Says on /diagnostics (ERROR) and in the log when the motor stalls, and when it ends.

    The ERROR is repeated every STALL_REPEAT_NS while it lasts, so monitors do not take it as
    stale.
    """

    def __init__(self, publisher: Publisher, logger: RcutilsLogger):
        self._publisher = publisher
        self._logger = logger
        self._reason: Optional[str] = None
        self._reported_ns = 0

    def update(self, stepper, stamp_ns: int) -> None:
        """Report the motor stepper's state at stamp_ns if it changed or is due again."""
        reason = stepper.stall_reason if stepper.stalled else None
        changed = reason != self._reason
        due = reason is not None and stamp_ns - self._reported_ns >= STALL_REPEAT_NS
        if not (changed or due):
            return
        self._reason, self._reported_ns = reason, stamp_ns
        if reason is None:
            level, text = DiagnosticStatus.OK, 'motor running: the stall is over'
            self._logger.info(text)
        else:
            level, text = DiagnosticStatus.ERROR, f'motor stalled: {reason}'
            if changed:
                self._logger.error(text)
        values = [KeyValue(key='stalled', value=str(reason is not None).lower()),
                  KeyValue(key='motor_torque', value=repr(stepper.motor_torque))]
        status = DiagnosticStatus(level=level, name=DRIVE_STATUS, hardware_id=MACHINE_NAME,
                                  message=text, values=values)
        self._publisher.publish(_array(status, stamp_message(stamp_ns)))
