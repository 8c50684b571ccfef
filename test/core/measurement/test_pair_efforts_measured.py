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
"""Effort figures measured from samples, against closed forms and the loads' work."""

import math

import numpy as np
import pytest

from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics.chain import efforts, Loads, MassProperties, ram_load_force
from qrm_ros.core.measurement.strokes import find_stroke_pairs, measure_pair_efforts, StrokePairs

PAPER = kin.Geometry.paper()


def _pairs(start, end):
    """StrokePairs holding only the windows (the measurement reads nothing else)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    filler = np.full(start.shape, np.nan)
    fields = dict.fromkeys(StrokePairs._fields, filler)
    fields.update(cutting_start=start, return_end=end)
    return StrokePairs(**fields)


def test_harmonic_torque_at_steady_speed_matches_closed_forms():
    """tau = a + b cos(w t) over whole periods: RMS^2 = a^2 + b^2 / 2, energy = a w T."""
    mean_torque, swing, speed, rate = 3.0, -5.0, 2.0 * math.pi, 20000.0
    t = np.arange(0.0, 3.2, 1.0 / rate)
    torque = mean_torque + swing * np.cos(speed * t)
    force = 7.0 * np.sin(speed * t)
    input_speed = np.full_like(t, speed)
    pairs = _pairs([0.25, 1.25], [1.25, 2.25])   # windows off the sample grid's phase
    measured = measure_pair_efforts(t, input_speed, torque, force, pairs)
    np.testing.assert_allclose(measured.energy_per_pair, mean_torque * 2.0 * math.pi,
                               rtol=1e-7)
    np.testing.assert_allclose(measured.mean_input_power, mean_torque * speed, rtol=1e-7)
    np.testing.assert_allclose(measured.rms_input_torque,
                               math.sqrt(mean_torque ** 2 + swing ** 2 / 2), rtol=1e-7)
    np.testing.assert_allclose(measured.peak_input_torque, abs(mean_torque) + abs(swing),
                               rtol=1e-7)
    np.testing.assert_allclose(measured.peak_offset_force, 7.0, rtol=1e-7)
    np.testing.assert_allclose(measured.speed_fluctuation, 0.0, atol=1e-12)


def test_window_ends_are_interpolated_not_snapped():
    """A ramp f = t integrated over [0.1234, 0.8765]: exact for a linear signal."""
    t = np.linspace(0.0, 1.0, 11)
    ones = np.ones_like(t)
    measured = measure_pair_efforts(t, ones, t, t, _pairs([0.1234], [0.8765]))
    assert measured.energy_per_pair[0] == pytest.approx((0.8765 ** 2 - 0.1234 ** 2) / 2,
                                                        rel=1e-13)
    assert measured.peak_input_torque[0] == pytest.approx(0.8765, rel=1e-13)


def test_speed_fluctuation_of_a_sinusoidal_speed():
    """w = W (1 + e sin(2 pi t / T)): Cs = 2 e, mean W (the angle swept over T)."""
    t = np.arange(0.0, 2.5, 1e-4)
    mean_speed, amplitude = 5.0, 0.03
    speed = mean_speed * (1.0 + amplitude * np.sin(2.0 * math.pi * t))
    zero = np.zeros_like(t)
    measured = measure_pair_efforts(t, speed, zero, zero, _pairs([0.1], [1.1]))
    assert measured.speed_fluctuation[0] == pytest.approx(2 * amplitude, rel=1e-6)


@pytest.mark.parametrize('offset', [0.0, 0.012, -0.015])
def test_energy_per_pair_is_the_loads_work(offset):
    """
    At steady speed, inertia and gravity give back what they take over a revolution, so the
    drive's work per pair is the loads' work: cutting_force x cutting_length (one cut per
    pair) + ram_friction x 2 x stroke. Sampled at 20 kHz, trapezoid error ~ jump x dt.
    """
    mass, loads = MassProperties.small_shaper(), Loads.small_shaper()
    speed, rate = 2.0 * math.pi, 20000.0
    t = np.arange(0.0, 3.0, 1.0 / rate)
    sample = kin.state(PAPER, offset, speed * t + 0.3, speed)
    stroke = PAPER.ram_stroke
    load = ram_load_force(loads, sample.ram_position, sample.ram_velocity, stroke)
    joint = efforts(PAPER, mass, offset, speed * t + 0.3, speed, external_ram_force=load)
    pairs = find_stroke_pairs(t, sample.ram_position, sample.ram_velocity)
    measured = measure_pair_efforts(t, np.full_like(t, speed), joint.input_torque,
                                    joint.offset_force, pairs)
    assert measured.energy_per_pair.size == 2
    expected = loads.cutting_force * loads.cutting_length + 2.0 * loads.ram_friction * stroke
    np.testing.assert_allclose(measured.energy_per_pair, expected, rtol=2e-4)
    period = 2.0 * math.pi / speed
    np.testing.assert_allclose(measured.mean_input_power, expected / period, rtol=2e-4)


def test_no_pairs_gives_empty_arrays():
    t = np.linspace(0.0, 1.0, 5)
    measured = measure_pair_efforts(t, t, t, t, _pairs([], []))
    assert all(field.size == 0 for field in measured)
