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
The shaper_sim node's stroke-pair reports: measured a step at a time between the ticks.

StrokeMonitor (qrm_ros.core.measurement.stroke_monitor) cuts the published samples into completed
stroke pairs; measuring a pair of thousands of samples takes about a millisecond, which no
tick may wait for. So each pair becomes a job of small steps, run after a tick while less
than PAIR_STEP_SHARE of the timer's period has gone since the tick began. Not on a thread:
there a pair held a 4 kHz node's ticks back for its whole length (the GIL), whatever the
switch interval. Each report carries the pair's effort theory, worked out in the background
(qrm_ros.core.measurement.effort_theory), when the setting held steady through the pair.
"""

from collections import deque
import threading
import time
from typing import Any, Deque, Generator, List, Optional, Tuple

from diagnostic_msgs.msg import KeyValue
from qrm_ros.core.dynamics.chain import Loads, MassProperties, MotorDrive
from qrm_ros.core.measurement.effort_theory import BackgroundTheory, Setting, THEORY_FIGURES
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.measurement.stroke_monitor import CompletedSamples, PairReport, StrokeMonitor
from qrm_ros.core.measurement.strokes import run_steps
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.node.shaper_sim.shaper_diagnostics import stroke_pair_status
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher

__all__ = ['PAIR_STEP_SHARE', 'StrokePairReports']

# Stroke-pair steps run after a tick while less than this fraction of the timer's period has
# gone since the tick began: the rest absorbs the host's noise.
PAIR_STEP_SHARE = 0.5


def _setting_speed(stepper) -> float:
    """Return the speed a steady pair runs at: the drive's, or the motor's reference."""
    if isinstance(stepper, MotorStepper):
        return stepper.speed_reference
    return stepper.input_speed


class StrokePairReports:
    """Measures completed stroke pairs and publishes their reports; see the module docstring."""

    def __init__(self, geometry: Geometry, publisher: Publisher, logger: RcutilsLogger,
                 publish_rate: float):
        self.monitor = StrokeMonitor(geometry)
        self._geometry = geometry
        self._publisher = publisher
        self._logger = logger
        self._theory = BackgroundTheory()
        self._jobs: Deque[Generator] = deque()
        self._lock = threading.Lock()  # one caller steps the jobs at a time
        # ns after a tick's start within which steps run (public: tests set it).
        self.step_budget_ns = round(PAIR_STEP_SHARE * NANOSECONDS_PER_SECOND / publish_rate)
        self._steps_waited = False  # the last tick ran no step: the next runs one
        self._published = 0
        # What the effort theory of a pair depends on, and since when (ns) it has held:
        # (stepper, mass, loads, motor, offset, speed).
        self._setting: Any = None
        self._setting_since_ns = 0
        # s a report waits for its effort theory; None: not at all (the live node never
        # waits; an offline run does, so that its reports do not depend on the CPU's speed).
        self.theory_timeout: Optional[float] = None
        # Whether the theory is worked out in this thread instead (an offline run, which has
        # no tick to keep: no worker to start, and the same function it would run).
        self.theory_in_this_thread = False

    @property
    def published(self) -> int:
        """How many stroke-pair statuses have been published."""
        return self._published

    def clear(self) -> None:
        """Drop the samples of the pair under way (it would span a reset, pause or switch)."""
        self.monitor.clear()

    def note_setting(self, stepper, mass: MassProperties, loads: Loads, motor: MotorDrive,
                     stamp_ns: int) -> float:
        """
        Note the setting in force at stamp_ns (a change starts a new steady span).

        Returns the speed it is set to (rad/s; a motor's reference), which the sample of
        stamp_ns carries to the stroke monitor.
        """
        # The parameter sets compare by identity: any change of them makes new ones.
        speed = _setting_speed(stepper)
        setting = (stepper, mass, loads, motor, stepper.offset, speed, stepper.geometry)
        if setting != self._setting:
            self._setting, self._setting_since_ns = setting, stamp_ns
        return speed

    def queue(self, completed: CompletedSamples, target: float, definition: str,
              time_ratio_target: float = 0.0) -> None:
        """Queue completed samples' pairs; what a report depends on is taken as it stands."""
        self._jobs.append(self._report(completed, self._setting, self._setting_since_ns,
                                       target, definition, time_ratio_target))

    def run_steps(self, started_ns: int) -> None:
        """
        Run stroke-pair steps, oldest pair first, while there is budget left.

        The budget is step_budget_ns (PAIR_STEP_SHARE of the timer's period) since started_ns
        (the tick's start). A tick that used it up itself runs none, unless the tick before
        ran none either: the pairs always progress. Skipped while wait_for_all steps them.
        """
        jobs = self._jobs
        if not jobs or not self._lock.acquire(blocking=False):
            return
        try:
            budget_ns = self.step_budget_ns
            ran = False
            while jobs:
                if (time.monotonic_ns() - started_ns >= budget_ns
                        and (ran or not self._steps_waited)):
                    self._steps_waited = not ran
                    return
                try:
                    next(jobs[0])
                except StopIteration:
                    jobs.popleft()
                ran = True
            self._steps_waited = False
        finally:
            self._lock.release()

    def wait_for_all(self, timeout: Optional[float] = None) -> None:
        """Report every pair completed so far, now, in this thread (for tests and tools)."""
        if not self._jobs:
            return  # a job leaves the queue only once reported: none waits (every tick offline)
        if not self._lock.acquire(timeout=-1 if timeout is None else timeout):
            raise TimeoutError('the stroke pairs are being reported by another caller')
        try:
            while self._jobs:
                run_steps(self._jobs.popleft())
        finally:
            self._lock.release()

    def close(self) -> None:
        """Report what is left (before the publisher goes), stop the theory's worker."""
        self.wait_for_all()
        self._theory.close()

    def _report(self, completed: CompletedSamples, setting: Any,
                setting_since_ns: int, target: float, definition: str,
                time_ratio_target: float) -> Generator:
        """Measure and publish completed stroke pairs, a step per next() (run_steps)."""
        try:
            for report in (yield from self.monitor.measure_steps(completed)):
                yield
                message = stroke_pair_status(
                    report, *self._effort_theory(report, setting, setting_since_ns), target,
                    definition, time_ratio_target)
                yield
                self._publisher.publish(message)
                self._published += 1
        except Exception as error:  # noqa: B902 said; the ticks and later pairs go on
            self._logger.error(f'stroke pair at {completed.stamp_ns} ns not reported: '
                               f'{type(error).__name__}: {error}')

    def _effort_theory(self, report: PairReport, setting: Any,
                       setting_since_ns: int) -> Tuple[List[KeyValue], str]:
        """Return the pair's effort theory as key-values, and a word on where it stands."""
        if report.pair_start * NANOSECONDS_PER_SECOND < setting_since_ns:
            return [], 'none: the setting changed during the pair'
        stepper, mass, loads, motor, offset, speed, geometry = setting
        wanted = Setting(geometry, mass, loads,
                         motor if isinstance(stepper, MotorStepper) else None, offset, speed)
        if self.theory_in_this_thread:
            theory, problem = self._theory.work_out(wanted)
        elif self.theory_timeout is None:
            theory, problem = self._theory.lookup(wanted)
        else:
            theory, problem = self._theory.wait(wanted, self.theory_timeout)
        if problem:
            return [], f'unavailable: {problem}'
        if theory is None:
            return [], 'pending: worked out in the background'
        values = [KeyValue(key=f'{name}_theory', value=repr(theory[name]))
                  for name in THEORY_FIGURES if theory[name] is not None]
        return values, ('steady setting' if values else
                        'none: no steady running at this setting (stopped or stalled)')
