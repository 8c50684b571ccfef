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
"""The steady effort theory and its background worker (no ROS)."""

import math
import os
import subprocess
import sys
import time

import pytest
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.effort_theory import (BackgroundTheory, Setting,
                                                    steady_effort_theory, THEORY_FIGURES,
                                                    WORKER_NICENESS)
from qrm_ros.core.dynamics.speed_drive import pair_efforts

GEOMETRY = kin.Geometry.paper()
LOADS = dyn.Loads(400.0, 20.0, 0.15)


def speed_drive_setting(offset=0.01, mass=None):
    return Setting(GEOMETRY, mass or dyn.MassProperties.small_shaper(), LOADS, None, offset,
                   2.0 * math.pi)


@pytest.fixture
def theory():
    worker = BackgroundTheory()
    yield worker
    worker.close()


def test_the_speed_drive_theory_is_pair_efforts_and_no_fluctuation():
    setting = speed_drive_setting()
    figures = steady_effort_theory(setting)
    exact = pair_efforts(GEOMETRY, setting.mass, LOADS, setting.offset, setting.input_speed)
    assert figures == {**exact._asdict(), 'speed_fluctuation': 0.0}
    assert all(type(value) is float for value in figures.values())


def test_no_theory_for_a_stopped_shaft_or_a_refused_offset():
    assert steady_effort_theory(speed_drive_setting()._replace(input_speed=0.0)) == dict.fromkeys(
        THEORY_FIGURES)
    at_the_radius = speed_drive_setting(offset=GEOMETRY.coupling_radius)
    assert steady_effort_theory(at_the_radius) == dict.fromkeys(THEORY_FIGURES)


def test_background_lookup_never_waits_then_answers_by_value(theory):
    setting = speed_drive_setting()
    assert theory.lookup(setting) == (None, None)  # started, not there yet
    figures, problem = theory.wait(setting)
    assert problem is None and figures == steady_effort_theory(setting)
    # Equal parameter sets made anew (as the node makes them) find the same answer.
    again = speed_drive_setting(mass=dyn.MassProperties.small_shaper())
    assert again.mass is not setting.mass
    assert theory.lookup(again) == (figures, None)


def test_worked_out_here_it_is_the_workers_answer_and_is_kept(theory):
    """An offline run works the theory out in its own thread: the worker's numbers, no worker."""
    setting = speed_drive_setting()
    here = BackgroundTheory()
    assert here.work_out(setting) == theory.wait(setting)
    assert here.worker_pid is None  # no worker was started
    assert here.lookup(setting) == here.work_out(setting)  # kept
    broken = speed_drive_setting(mass=dyn.MassProperties.small_shaper())._replace(loads=None)
    figures, problem = here.work_out(broken)
    assert figures is None and problem.startswith('AttributeError')


def test_a_failing_theory_is_a_problem_with_its_reason_not_an_exception(theory):
    broken = speed_drive_setting()._replace(loads=None)  # not a Loads: the worker raises
    figures, problem = theory.wait(broken)
    assert figures is None and problem.startswith('AttributeError')


SCRIPT = '''
import math, os, sys
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.effort_theory import BackgroundTheory, Setting
print('script ran', flush=True)  # once: the worker must not run the caller's script
theory = BackgroundTheory()
setting = Setting(kin.Geometry.paper(), dyn.MassProperties.small_shaper(), dyn.Loads.none(),
                  None, 0.0, 2 * math.pi)
figures, problem = theory.wait(setting)
print('worker', theory.worker_pid, os.getpriority(os.PRIO_PROCESS, theory.worker_pid),
      figures['peak_input_torque'] > 0.0, problem, flush=True)
if sys.argv[1:] == ['hang']:
    sys.stdin.read()
theory.close()
'''


def test_the_worker_runs_no_script_of_the_caller_and_runs_nice(tmp_path):
    script = tmp_path / 'unguarded.py'  # no `if __name__ == '__main__'`
    script.write_text(SCRIPT)
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines.count('script ran') == 1, result.stdout
    _, _, niceness, positive, problem = lines[-1].split()
    assert int(niceness) == os.getpriority(os.PRIO_PROCESS, 0) + WORKER_NICENESS
    assert (positive, problem) == ('True', 'None')


def test_the_worker_ends_with_its_caller_however_it_ends(tmp_path):
    script = tmp_path / 'killed.py'
    script.write_text(SCRIPT)
    caller = subprocess.Popen([sys.executable, str(script), 'hang'], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert caller.stdout.readline() == 'script ran\n'
        worker = int(caller.stdout.readline().split()[1])
    finally:
        caller.kill()  # no close(): the worker sees its input end
        caller.wait()
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        try:
            os.kill(worker, 0)
        except ProcessLookupError:
            return
        with open(f'/proc/{worker}/stat') as stat:
            if stat.read().split()[2] == 'Z':  # ended, not yet reaped (its parent is gone)
                return
        time.sleep(0.05)
    raise AssertionError(f'the worker {worker} outlived its caller')
