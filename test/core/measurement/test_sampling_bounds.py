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
core.measurement.sampling_bounds against the stroke finder run on the exact motion at every phase.

The closed-form motion is sampled at a coarse step starting at many input angles; every
pair the stroke finder measures must lie within the stated bound of the closed form (the
bound holds for any phase: it is a worst case, not an estimate).
"""

import math

import numpy as np
import pytest

from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.sampling_bounds import (BOUNDED_FIGURES, figure_sampling_bounds,
                                                      steady_motion, SUPPORTED_RELATIVE_ERROR)
from qrm_ros.core.measurement.strokes import find_stroke_pairs

PAPER = kin.Geometry.paper()
SPEED = 2 * math.pi
PAIR_FIGURES = ('time_ratio', 'speed_ratio', 'peak_speed_ratio', 'cutting_time',
                'return_time', 'peak_cutting_speed', 'peak_return_speed')


def _pairs(offset, step, phase, speed=SPEED):
    time = np.arange(0.0, 6.0, step)
    state = kin.state(PAPER, offset, phase + speed * time, speed)
    return find_stroke_pairs(time, state.ram_position, state.ram_velocity)


@pytest.mark.parametrize('offset', [-0.015, 0.0, 0.01, 0.015])
@pytest.mark.parametrize('rate', [25.0, 50.0, 100.0])
def test_every_pair_at_every_phase_lies_within_the_bound(offset, rate):
    theory = kin.steady_theory(PAPER, offset, SPEED)._asdict()
    bounds = figure_sampling_bounds(PAPER, offset, SPEED, 1.0 / rate)
    for phase in np.linspace(0.0, 2 * math.pi, 16, endpoint=False):
        pairs = _pairs(offset, 1.0 / rate, phase)
        assert pairs.time_ratio.size >= 3
        for name in PAIR_FIGURES:
            if bounds[name] is None:
                continue
            error = np.max(np.abs(getattr(pairs, name) - theory[name]))
            assert error <= bounds[name] + 1e-9 * abs(theory[name]), (name, phase)


def test_reverse_running_is_bounded_alike():
    theory = kin.steady_theory(PAPER, 0.01, -SPEED)._asdict()
    bounds = figure_sampling_bounds(PAPER, 0.01, -SPEED, 0.04)
    for phase in np.linspace(0.0, 2 * math.pi, 8, endpoint=False):
        pairs = _pairs(0.01, 0.04, phase, -SPEED)
        for name in PAIR_FIGURES:
            if bounds[name] is not None:
                assert np.max(np.abs(getattr(pairs, name) - theory[name])) <= bounds[name]


def test_fine_sampling_supports_every_figure():
    for offset in (-0.015, 0.0, 0.015):
        theory = kin.steady_theory(PAPER, offset, SPEED)._asdict()
        bounds = figure_sampling_bounds(PAPER, offset, SPEED, 0.005)
        for name in PAIR_FIGURES:
            assert bounds[name] < SUPPORTED_RELATIVE_ERROR * abs(theory[name])


@pytest.mark.parametrize('offset', [0.02499999, -0.02499999, 0.025, math.nan])
def test_a_motion_too_sharp_for_a_bounded_grid_has_no_bound(offset):
    assert steady_motion(PAPER, offset) is None
    assert set(figure_sampling_bounds(PAPER, offset, SPEED, 0.01).values()) == {None}


@pytest.mark.parametrize('speed, step', [(0.0, 0.01), (SPEED, 0.0), (SPEED, math.inf),
                                         (math.nan, 0.01)])
def test_no_bound_without_a_speed_or_a_step(speed, step):
    assert set(figure_sampling_bounds(PAPER, 0.01, speed, step).values()) == {None}


def test_bounds_are_figures_of_the_listed_kinds():
    assert set(figure_sampling_bounds(PAPER, 0.01, SPEED, 0.01)) == set(BOUNDED_FIGURES)
