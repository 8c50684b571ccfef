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
"""Stroke finder on sampled trajectories, against closed forms."""

import math

import numpy as np
import pytest

from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.strokes import find_reversals, find_stroke_pairs

PAPER = kin.Geometry.paper()


def test_harmonic_motion_reversals_and_peaks_are_exact_to_interpolation_order():
    """x = A cos(w t): reversals at t = k pi / w, peaks A w at the mid-points, TR = SR = 1."""
    amplitude, omega, rate = 0.1, 2.0 * math.pi, 100.0
    t = np.arange(0.0, 3.3, 1.0 / rate) + 0.00123
    x, v = amplitude * np.cos(omega * t), -amplitude * omega * np.sin(omega * t)
    when, cut_begins, _ = find_reversals(t, x, v)
    expected = np.arange(1, 7) * math.pi / omega
    np.testing.assert_allclose(when, expected, atol=1e-6)
    assert list(cut_begins) == [False, True, False, True, False, True]
    pairs = find_stroke_pairs(t, x, v)
    assert len(pairs.time_ratio) == 2
    np.testing.assert_allclose(pairs.cutting_start, [1.0, 2.0], atol=1e-6)
    np.testing.assert_allclose(pairs.time_ratio, 1.0, rtol=1e-6)
    np.testing.assert_allclose(pairs.peak_cutting_speed, amplitude * omega, rtol=1e-6)
    np.testing.assert_allclose(pairs.mid_return_speed, amplitude * omega, rtol=1e-6)
    np.testing.assert_allclose(pairs.speed_ratio, 1.0, rtol=1e-6)


@pytest.mark.parametrize('offset', [-0.015, -0.008, 0.0, 0.01, 0.015])
@pytest.mark.parametrize('input_speed', [2 * math.pi, -2 * math.pi, 9.0])
def test_sampled_mechanism_at_100_hz_matches_closed_form(offset, input_speed):
    """
    Ratios agree with theory within (|w| dt)^3, the Hermite velocity's error order.

    That is 2.5e-4 at 2 pi rad/s and 100 Hz (the node's defaults), 7.3e-4 at 9 rad/s.
    """
    step = 0.01
    tolerance = (abs(input_speed) * step) ** 3
    t = np.arange(0.0, 4.0, step)
    s = kin.state(PAPER, offset, 0.37 + input_speed * t, input_speed)
    pairs = find_stroke_pairs(t, s.ram_position, s.ram_velocity)
    assert len(pairs.time_ratio) >= 2
    cutting_time, return_time = kin.stroke_times(PAPER, offset, input_speed)
    np.testing.assert_allclose(pairs.cutting_time, cutting_time, rtol=tolerance)
    np.testing.assert_allclose(pairs.return_time, return_time, rtol=tolerance)
    np.testing.assert_allclose(pairs.time_ratio, kin.time_ratio(PAPER, offset, input_speed),
                               rtol=tolerance)
    np.testing.assert_allclose(pairs.speed_ratio, kin.speed_ratio(PAPER, offset, input_speed),
                               rtol=tolerance)
    cutting, returning = kin.peak_ram_speeds(PAPER, offset, input_speed)
    np.testing.assert_allclose(pairs.peak_cutting_speed, cutting, rtol=tolerance)
    np.testing.assert_allclose(pairs.peak_return_speed, returning, rtol=tolerance)
    np.testing.assert_allclose(pairs.peak_speed_ratio,
                               kin.peak_speed_ratio(PAPER, offset, input_speed), rtol=tolerance)
    # Mean cutting speed: the stroke (the ram's end positions are fixed by the lever's
    # tangent positions, whatever the offset) over the exact cutting time.
    np.testing.assert_allclose(pairs.mean_cutting_speed, PAPER.ram_stroke / cutting_time,
                               rtol=tolerance)


def test_error_shrinks_as_sampling_gets_denser():
    offset, input_speed = 0.012, 2 * math.pi
    errors = []
    for rate in (50.0, 100.0, 200.0):
        t = np.arange(0.0, 3.0, 1.0 / rate)
        s = kin.state(PAPER, offset, input_speed * t, input_speed)
        pairs = find_stroke_pairs(t, s.ram_position, s.ram_velocity)
        errors.append(np.max(np.abs(pairs.peak_speed_ratio
                                    / kin.peak_speed_ratio(PAPER, offset) - 1.0)))
    assert errors[2] < errors[1] / 4 < errors[0] / 16


def test_reversal_exactly_on_a_sample_is_counted_once():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    x = np.array([-1.0, 0.0, 1.0, 0.0])
    v = np.array([1.0, 1.0, 0.0, -1.0])
    when, cut_begins, _ = find_reversals(t, x, v)
    assert list(when) == [2.0]
    assert list(cut_begins) == [True]


@pytest.mark.parametrize('samples', [0, 1, 2, 10])
def test_too_short_runs_give_no_pairs(samples):
    t = np.arange(samples) * 0.01
    pairs = find_stroke_pairs(t, np.sin(t), np.cos(t))
    assert all(len(field) == 0 for field in pairs)
