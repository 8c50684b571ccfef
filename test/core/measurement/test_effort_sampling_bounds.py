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
The effort figures' sampling bounds against the true error of the piecewise measurement.

The ideal speed drive's efforts are sampled at several rates and sampling phases, measured
as the analysis measures them (the switches found from the sampled motion) and compared
with speed_drive.pair_efforts' exact figures: every stated bound covers the error, and at
250 Hz and 60 rpm every bound is below 1e-3 of its figure up to 15 mm.
"""

import math
import time

import numpy as np
import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.effort_sampling_bounds import (EFFORT_BOUNDED_FIGURES,
                                                             effort_sampling_bounds,
                                                             steady_efforts)
from qrm_ros.core.measurement.sampling_bounds import steady_motion, SUPPORTED_RELATIVE_ERROR
from qrm_ros.core.dynamics.speed_drive import pair_efforts
from qrm_ros.core.measurement.strokes import measure_pair_efforts

from synthetic_run import sampled_speed_drive

PAPER = kin.Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()
SPEED = 2 * math.pi
FIGURES = ('peak_input_torque', 'rms_input_torque', 'mean_input_power', 'energy_per_pair',
           'peak_offset_force')


def _measured(offset, rate, phase, loads=LOADS, speed=SPEED):
    t, joint, pairs, edges = sampled_speed_drive(offset, rate, phase,
                                                 3.3 * 2 * math.pi / abs(speed), loads, speed,
                                                 MASS)
    return measure_pair_efforts(t, np.full_like(t, speed), joint.input_torque,
                                joint.offset_force, pairs, edges), float(np.max(np.diff(t)))


def _bounds(offset, step, loads=LOADS, speed=SPEED):
    exact = pair_efforts(PAPER, MASS, loads, offset, speed)
    return exact, effort_sampling_bounds(steady_efforts(PAPER, MASS, loads, offset, speed),
                                         steady_motion(PAPER, offset), exact._asdict(), speed,
                                         step)


@pytest.mark.parametrize('offset', [-0.015, -0.0111, -0.005, 0.0, 0.005, 0.01, 0.015])
@pytest.mark.parametrize('rate', [100.0, 250.0, 500.0, 1000.0])
def test_every_stated_bound_covers_the_true_error(offset, rate):
    bounded = 0
    for phase in np.linspace(0.0, 1.0, 5, endpoint=False):
        measured, step = _measured(offset, rate, phase)
        exact, bounds = _bounds(offset, step)
        assert bounds['speed_fluctuation'] == 0.0
        for name in FIGURES:
            if bounds[name] is None:
                continue
            bounded += 1
            error = np.max(np.abs(getattr(measured, name) - getattr(exact, name)))
            assert error <= bounds[name], (name, phase, error, bounds[name])
    if rate >= 250.0:
        assert bounded == 5 * len(FIGURES)
        for name in FIGURES:
            assert bounds[name] < SUPPORTED_RELATIVE_ERROR * abs(getattr(exact, name)), name


@pytest.mark.parametrize('speed', [-2 * math.pi, 9.0])
def test_other_speeds_and_the_reverse_are_covered_too(speed):
    rate = 600.0
    for phase in (0.0, 0.5):
        measured, step = _measured(0.01, rate, phase, speed=speed)
        exact, bounds = _bounds(0.01, step, speed=speed)
        for name in FIGURES:
            assert bounds[name] is not None, name
            error = np.max(np.abs(getattr(measured, name) - getattr(exact, name)))
            assert error <= bounds[name], (name, error, bounds[name])


def test_without_loads_the_bounds_hold_and_the_work_is_zero():
    free = dyn.Loads.none()
    measured, step = _measured(0.008, 400.0, 0.3, loads=free)
    exact, bounds = _bounds(0.008, step, loads=free)
    for name in FIGURES:
        error = np.max(np.abs(getattr(measured, name) - getattr(exact, name)))
        assert bounds[name] is not None and error <= bounds[name], name


@pytest.mark.parametrize('samples_per_revolution', [2.5, 10.0])
def test_coarse_sampling_has_no_bound(samples_per_revolution):
    _, bounds = _bounds(0.0, 2 * math.pi / SPEED / samples_per_revolution)
    assert all(bounds[name] is None for name in FIGURES)


def test_bounds_shrink_as_the_fourth_power_of_the_step():
    _, coarse = _bounds(-0.005, 1.0 / 400.0)
    _, fine = _bounds(-0.005, 1.0 / 800.0)
    for name in FIGURES:
        assert fine[name] < coarse[name] / 8.0, name


def test_the_motor_drive_and_missing_theory_have_no_bound():
    motion = steady_motion(PAPER, 0.01)
    theory = pair_efforts(PAPER, MASS, LOADS, 0.01, SPEED)._asdict()
    assert effort_sampling_bounds(None, motion, theory, SPEED, 0.001) == dict.fromkeys(
        EFFORT_BOUNDED_FIGURES)
    efforts = steady_efforts(PAPER, MASS, LOADS, 0.01, SPEED)
    assert set(effort_sampling_bounds(efforts, motion, dict.fromkeys(theory), SPEED,
                                      0.001).values()) == {None}


def test_cost_is_bounded_a_hair_below_the_coupling_radius():
    started = time.monotonic()
    near = PAPER.coupling_radius * (1 - 1e-9)
    found = steady_efforts(PAPER, MASS, LOADS, near, SPEED)
    assert time.monotonic() - started < 30.0  # generous: a loaded machine; typically < 1 s
    if found is not None:
        assert all(np.all(np.isfinite(part)) for parts in found.signals.values()
                   for part in parts)
    assert steady_efforts(PAPER, MASS, LOADS, PAPER.coupling_radius, SPEED) is None
