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

import pytest
from qrm_ros import dynamics as dyn
from qrm_ros import kinematics as kin
from qrm_ros.effort_theory import (BackgroundTheory, Setting, steady_effort_theory,
                                   THEORY_FIGURES)
from qrm_ros.motor_drive import pair_efforts

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
    figures, problem = theory.wait(setting, timeout=60.0)
    assert problem is None and figures == steady_effort_theory(setting)
    # Equal parameter sets made anew (as the node makes them) find the same answer.
    again = speed_drive_setting(mass=dyn.MassProperties.small_shaper())
    assert again.mass is not setting.mass
    assert theory.lookup(again) == (figures, None)


def test_a_failing_theory_is_a_problem_with_its_reason_not_an_exception(theory):
    broken = speed_drive_setting()._replace(loads=None)  # not a Loads: the worker raises
    figures, problem = theory.wait(broken, timeout=60.0)
    assert figures is None and problem.startswith('AttributeError')
