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
Mean cutting speed (stroke / cutting time) and its inversion, against independent routes.

The sampled route finds the ram's reversals as zeros of its velocity along the input angle
(never inverting the coupling) and measures the stroke between them; the closed-form route
solves the coupling's geometry for crank_phase = 0 by hand (derivation in the test).
"""

import math

import numpy as np
import pytest
from scipy import optimize

from qrm_ros.core import kinematics as kin

PAPER = kin.Geometry.paper()
PHASED = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=0.4)
BACKWARD_PHASED = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=2.5)
OFFSETS = [-0.0225, -0.012, -0.005, 0.0, 0.005, 0.0111, 0.02, 0.0225]


def sampled_mean_cutting_speed(geometry, offset, input_speed):
    """Stroke and cutting time from the ram velocity's zeros over one input revolution."""
    def velocity(theta):
        return kin.state(geometry, offset, float(theta), input_speed).ram_velocity

    grid = np.linspace(0.0, 2 * math.pi, 4001)
    sampled = np.asarray(kin.state(geometry, offset, grid, input_speed).ram_velocity)
    crossings = np.nonzero(np.sign(sampled[:-1]) != np.sign(sampled[1:]))[0]
    assert len(crossings) == 2
    zeros = [optimize.brentq(velocity, grid[i], grid[i + 1], xtol=1e-15) for i in crossings]
    # The cut moves the ram toward -x: it runs while the velocity is negative.
    middle = 0.5 * (zeros[0] + zeros[1])
    inside_is_cut = velocity(middle) < 0.0
    arc = zeros[1] - zeros[0] if inside_is_cut else 2 * math.pi - (zeros[1] - zeros[0])
    positions = [kin.state(geometry, offset, z, input_speed).ram_position for z in zeros]
    stroke = abs(positions[1] - positions[0])
    return stroke / (arc / abs(input_speed))


@pytest.mark.parametrize('geometry', [PAPER, PHASED, BACKWARD_PHASED])
@pytest.mark.parametrize('offset', OFFSETS)
@pytest.mark.parametrize('input_speed', [3.0, -7.5])
def test_mean_cutting_speed_matches_sampled_strokes(geometry, offset, input_speed):
    expected = sampled_mean_cutting_speed(geometry, offset, input_speed)
    assert kin.mean_cutting_speed(geometry, offset, input_speed) == pytest.approx(
        expected, rel=1e-11)


def closed_form_offset(geometry, input_speed, cutting_speed):
    """
    Offset for a mean cutting speed, solved by hand for crank_phase = 0 and forward running.

    The reversals are mirror images about the y axis (flywheel at -a and pi + a, a =
    asin(r/h)), and so is the coupling, so the cut's input arc is pi - 2 b, b being the
    input angle at the cut's start. That pin, O1 + r1 (cos b, sin b), lies on the ray from O2
    at angle -a: r1 cos b sin a + (offset + r1 sin b) cos a = 0, so
    offset = -r1 sin(b + a) / cos a.
    """
    half_gap = math.asin(geometry.crank_radius / geometry.pivot_distance)
    arc = geometry.ram_stroke * input_speed / cutting_speed
    start = 0.5 * (math.pi - arc)
    return -geometry.coupling_radius * math.sin(start + half_gap) / math.cos(half_gap)


@pytest.mark.parametrize('cutting_speed', [0.1, 0.125, 0.147357, 0.2, 0.3])
def test_offset_for_mean_cutting_speed_is_the_closed_form(cutting_speed):
    offset = kin.offset_for_mean_cutting_speed(PAPER, 3.0, cutting_speed)
    assert offset == pytest.approx(closed_form_offset(PAPER, 3.0, cutting_speed),
                                   rel=1e-12, abs=1e-17)


@pytest.mark.parametrize('geometry', [PAPER, PHASED, BACKWARD_PHASED])
@pytest.mark.parametrize('input_speed', [2.0, -5.0])
def test_offset_for_mean_cutting_speed_round_trips_vectorised(geometry, input_speed):
    offsets = np.array(OFFSETS)
    speeds = kin.mean_cutting_speed(geometry, offsets, input_speed)
    found = kin.offset_for_mean_cutting_speed(geometry, input_speed, speeds)
    assert found.shape == offsets.shape
    np.testing.assert_allclose(found, offsets, rtol=0, atol=1e-15)
    # Broadcast over input speeds too: one target, three speeds.
    speeds = np.array([1.8, 2.0, 2.2]) * np.sign(input_speed)
    target = kin.mean_cutting_speed(geometry, 0.007, speeds[1])
    found = kin.offset_for_mean_cutting_speed(geometry, speeds, target)
    np.testing.assert_allclose(kin.mean_cutting_speed(geometry, found, speeds), target,
                               rtol=1e-13)


@pytest.mark.parametrize('phase', np.linspace(-math.pi, math.pi, 13))
def test_mean_cutting_speed_is_monotone_with_the_sign_of_cos_phase(phase):
    geometry = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=phase)
    offsets = np.linspace(-0.0249, 0.0249, 501)
    speeds = kin.mean_cutting_speed(geometry, offsets, 1.0)
    steps = np.diff(speeds)
    if abs(math.cos(phase)) < 1e-9:  # +-pi/2: the offset acts along the line of symmetry
        np.testing.assert_allclose(speeds, speeds[0], rtol=1e-12)
    elif math.cos(phase) > 0.0:
        assert np.all(steps < 0.0)  # a positive offset slows the cut, as for the paper
    else:
        assert np.all(steps > 0.0)


@pytest.mark.parametrize('offset', OFFSETS)
def test_both_cutting_speeds_are_proportional_to_input_speed(offset):
    unit_mean = kin.mean_cutting_speed(PAPER, offset, 1.0)
    unit_peak = kin.peak_ram_speeds(PAPER, offset, 1.0)[0]
    for input_speed in (0.5, 3.0, 40.0):
        assert kin.mean_cutting_speed(PAPER, offset, input_speed) == pytest.approx(
            unit_mean * input_speed, rel=1e-14)
        assert kin.peak_ram_speeds(PAPER, offset, input_speed)[0] == pytest.approx(
            unit_peak * input_speed, rel=1e-12)


def test_mean_is_below_peak_and_positive():
    offsets = np.linspace(-0.0225, 0.0225, 41)
    mean = kin.mean_cutting_speed(PAPER, offsets, 2.0)
    peak = kin.peak_ram_speeds(PAPER, offsets, 2.0)[0]
    assert np.all(mean > 0.0)
    assert np.all(mean < peak)


def test_unreachable_mean_cutting_speed_states_the_reachable_range():
    with pytest.raises(kin.KinematicsError) as error:
        kin.offset_for_mean_cutting_speed(PAPER, 1.0, [0.05, 0.5])
    message = str(error.value)
    assert 'cutting_speed 0.5 m/s is out of reach at input_speed 1 rad/s' in message
    slowest, fastest = (float(v) for v in message.split('from ')[1].split(' m/s')[0].split(
        ' to '))
    limit = (1 - 1e-9) * PAPER.coupling_radius
    assert slowest == pytest.approx(kin.mean_cutting_speed(PAPER, limit, 1.0), rel=1e-5)
    assert fastest == pytest.approx(kin.mean_cutting_speed(PAPER, -limit, 1.0), rel=1e-5)


@pytest.mark.parametrize('cutting_speed, words', [
    (0.0, 'cutting_speed must be > 0 m/s'), (-0.1, 'cutting_speed must be > 0 m/s'),
    (float('nan'), 'cutting_speed must be finite'), ('fast', 'cutting_speed must be a real'),
])
def test_bad_mean_cutting_speed_is_refused(cutting_speed, words):
    with pytest.raises(kin.KinematicsError, match=words):
        kin.offset_for_mean_cutting_speed(PAPER, 1.0, cutting_speed)


def test_bad_input_speed_and_offset_are_refused():
    with pytest.raises(kin.KinematicsError, match='input_speed must be non-zero'):
        kin.offset_for_mean_cutting_speed(PAPER, 0.0, 0.1)
    with pytest.raises(kin.KinematicsError, match='input_speed must be non-zero'):
        kin.mean_cutting_speed(PAPER, 0.0, 0.0)
    with pytest.raises(kin.KinematicsError, match='offset 0.03 m is out of range'):
        kin.mean_cutting_speed(PAPER, 0.03, 1.0)


def test_the_readme_examples():
    assert kin.mean_cutting_speed(PAPER, 0.0, 2 * math.pi) == pytest.approx(0.308625, abs=5e-7)
    assert kin.offset_for_mean_cutting_speed(PAPER, 2 * math.pi, 0.3) == pytest.approx(
        0.0016333, abs=5e-8)
