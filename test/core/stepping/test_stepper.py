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
Both steppers offer the node the one interface, ``Stepper``: checked by mypy and at run time.

mypy checks each class against the protocol where an instance is taken as a Stepper; a class
missing a member is refused (so the check checks something).
"""

import math
import os
import subprocess
import sys

import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.stepping.stepper import Stepper
from qrm_ros.core.stepping.stepping import ShaperStepper
from repo_paths import REPO_ROOT as ROOT

CHECKED = '''
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.stepping.stepper import Stepper
from qrm_ros.core.stepping.stepping import ShaperStepper


def held_by_the_node(shaper: ShaperStepper, motor: MotorStepper) -> list[Stepper]:
    return [shaper, motor]
'''
MISSING_A_MEMBER = '''
from qrm_ros.core.stepping.stepper import Stepper
from qrm_ros.core.stepping.stepping import ShaperStepper


class WithoutRestore(ShaperStepper):
    restore = None  # type: ignore[assignment]


def held_by_the_node(stepper: WithoutRestore) -> Stepper:
    return stepper
'''


def _mypy(source):
    pytest.importorskip('mypy')
    return subprocess.run(
        [sys.executable, '-m', 'mypy', '--ignore-missing-imports', '--no-error-summary',
         '--cache-dir', os.path.join(ROOT, '.mypy_cache'), '-c', source],
        capture_output=True, text=True, cwd=ROOT)


def test_mypy_takes_both_steppers_as_a_stepper():
    result = _mypy(CHECKED)
    assert result.returncode == 0, result.stdout + result.stderr


def test_mypy_refuses_a_stepper_missing_a_member():
    result = _mypy(MISSING_A_MEMBER)
    assert result.returncode == 1 and 'Stepper' in result.stdout, result.stdout + result.stderr


def test_both_steppers_are_steppers_at_run_time():
    geometry = Geometry.paper()
    shaper = ShaperStepper(geometry, 2 * math.pi, 0.01, 50.0, 0.01)
    motor = MotorStepper(geometry, dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper(),
                         dyn.MotorDrive.small_shaper(), 2 * math.pi, 0.01, 50.0, 0.01)
    assert isinstance(shaper, Stepper) and isinstance(motor, Stepper)
    assert not isinstance(object(), Stepper)
