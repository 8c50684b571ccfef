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
The piecewise effort measurement: its pieces' cubics, its edges, its figures against theory.

Closed forms: a cubic on each side of a jump is integrated exactly and its one-sided limits
are the peaks; the workpiece's edges are speed_drive.load_switch_angles' (closed form on
the flywheel); the ideal speed drive's figures are speed_drive.pair_efforts' (adaptive
Gauss-Legendre on the exact efforts).
"""

import math

import numpy as np
import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.piecewise_efforts import MIN_PIECE_SAMPLES, piecewise_figures
from qrm_ros.core.dynamics.speed_drive import load_switch_angles, pair_efforts
from qrm_ros.core.measurement.strokes import (find_stroke_pairs, measure_pair_efforts,
                                              workpiece_edge_times)

from synthetic_run import sampled_speed_drive

PAPER = kin.Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()
SPEED = 2 * math.pi


def test_cubics_either_side_of_a_jump_are_integrated_exactly_with_their_one_sided_limits():
    t = np.arange(0.0, 2.0, 0.037)  # the jump at 0.9 and the window's ends off the samples
    before = 1.0 + 2.0 * t - 3.0 * t ** 2 + 0.5 * t ** 3
    after = -4.0 + t ** 3
    signal = np.where(t < 0.9, before, after)
    found = piecewise_figures(t, [0.1, 0.9, 1.9], [0.1], [1.9], [signal], [signal])

    def primitive(x, c):
        return sum(value * x ** (k + 1) / (k + 1) for k, value in enumerate(c))
    first, second = (1.0, 2.0, -3.0, 0.5), (-4.0, 0.0, 0.0, 1.0)
    exact = (primitive(0.9, first) - primitive(0.1, first) + primitive(1.9, second)
             - primitive(0.9, second))
    assert found.integrals[0][0] == pytest.approx(exact, rel=1e-12)
    limits = [1.0 + 2.0 * x - 3.0 * x ** 2 + 0.5 * x ** 3 for x in (0.1, 0.9)]
    peaks = [max(limits + [-4.0 + 1.9 ** 3]), min(limits + [-4.0 + 0.9 ** 3])]
    # the first cubic turns inside its piece: its maximum there counts too
    turn = (3.0 - math.sqrt(9.0 - 3.0)) / 1.5
    peaks[0] = max(peaks[0], 1.0 + 2.0 * turn - 3.0 * turn ** 2 + 0.5 * turn ** 3)
    assert found.highest[0][0] == pytest.approx(peaks[0], rel=1e-12)
    assert found.lowest[0][0] == pytest.approx(peaks[1], rel=1e-12)
    assert not found.sparse[0]


def test_a_piece_with_few_samples_is_said():
    t = np.linspace(0.0, 1.0, 41)
    found = piecewise_figures(t, [0.0, 0.5, 0.5 + 0.025 * (MIN_PIECE_SAMPLES - 1.5), 1.0],
                              [0.0], [1.0], [t], [t])
    assert found.sparse[0]


@pytest.mark.parametrize('offset', [-0.015, 0.0, 0.012])
def test_edges_are_found_where_the_closed_form_puts_them(offset):
    rate = 200.0
    t = np.arange(0.0, 3.5, 1.0 / rate)
    angle = SPEED * t + 0.3
    motion = kin.state(PAPER, offset, angle, SPEED)
    pairs = find_stroke_pairs(t, motion.ram_position, motion.ram_velocity)
    edges = workpiece_edge_times(t, motion.ram_position, motion.ram_velocity,
                                 pairs.cutting_start, pairs.cutting_end, LOADS.cutting_length)
    theory = np.asarray(load_switch_angles(PAPER, LOADS, offset))[2:]
    assert edges.size == 2 * pairs.cutting_start.size
    for edge in edges:
        turns = (SPEED * edge + 0.3 - theory) / (2 * math.pi)
        assert np.min(np.abs(turns - np.round(turns))) * 2 * math.pi < 1e-7
    assert workpiece_edge_times(t, motion.ram_position, motion.ram_velocity,
                                pairs.cutting_start, pairs.cutting_end, 0.0).size == 0


def _sampled(offset, rate, phase=0.0, duration=3.5):
    return sampled_speed_drive(offset, rate, phase, duration, LOADS, SPEED, MASS)


@pytest.mark.parametrize('offset', [-0.015, 0.0, 0.015])
def test_split_at_the_switches_the_figures_are_far_closer_than_linear(offset):
    """500 Hz: the linear measure's first-order error at the jumps, gone."""
    t, joint, pairs, edges = _sampled(offset, 500.0, phase=0.37)
    speed = np.full_like(t, SPEED)
    linear = measure_pair_efforts(t, speed, joint.input_torque, joint.offset_force, pairs)
    pieces = measure_pair_efforts(t, speed, joint.input_torque, joint.offset_force, pairs,
                                  edges)
    exact = pair_efforts(PAPER, MASS, LOADS, offset, SPEED)
    for name in ('peak_input_torque', 'rms_input_torque', 'energy_per_pair',
                 'mean_input_power', 'peak_offset_force'):
        theory = getattr(exact, name)
        error = np.max(np.abs(getattr(pieces, name) / theory - 1.0))
        assert error < 1e-5, name
        assert error < 0.1 * np.max(np.abs(getattr(linear, name) / theory - 1.0)) + 1e-9, name


def test_without_edges_the_measure_is_the_linear_one():
    t, joint, pairs, _ = _sampled(0.01, 100.0)
    speed = np.full_like(t, SPEED)
    plain = measure_pair_efforts(t, speed, joint.input_torque, joint.offset_force, pairs)
    again = measure_pair_efforts(t, speed, joint.input_torque, joint.offset_force, pairs, None)
    for field, other in zip(plain, again):
        np.testing.assert_array_equal(field, other)
