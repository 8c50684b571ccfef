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
Kinematics core against independent derivations.

Each expected value comes from a different route than the code under test: the paper's and
the design note's formulas written out here, a numerical vector-loop solver, finite
differences, RK4 integration of the paper's eq. (20), or brute-force dense sampling.
"""

import math

import numpy as np
import pytest
from scipy import optimize

from qrm_ros.core import kinematics as kin

PAPER = kin.Geometry.paper()
OFFSETS = [-0.02, -0.015, -0.0111725663716814, -0.005, 0.0, 0.005, 0.01, 0.015, 0.02]
PHASED = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=0.4)


def loop_closure_positions(geometry, offset, input_angle):
    """Solve the two vector loops numerically (no closed form) for phi, psi and x."""
    r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
    pin = np.array([r1 * math.cos(input_angle), offset + r1 * math.sin(input_angle)])

    def coupling(unknowns):  # O2 + r2 (cos phi, sin phi) = pin
        phi, r2 = unknowns
        return [r2 * math.cos(phi) - pin[0], r2 * math.sin(phi) - pin[1]]

    phi, _ = optimize.fsolve(coupling, [input_angle, r1], xtol=1e-12)
    crank = geometry.crank_phase + phi
    crank_pin = np.array([r * math.cos(crank), r * math.sin(crank)])

    def lever(unknowns):  # O3 + R (sin psi, cos psi) = crank pin, O3 = (0, -h)
        psi, length = unknowns
        return [length * math.sin(psi) - crank_pin[0], length * math.cos(psi) - h - crank_pin[1]]

    psi, _ = optimize.fsolve(lever, [0.0, h], xtol=1e-12)

    def ram(unknowns):  # the block at height H above O3 lies on the lever line
        (x,) = unknowns
        return [x * math.cos(psi) - geometry.ram_height * math.sin(psi)]

    (x,) = optimize.fsolve(ram, [0.0], xtol=1e-12)
    return phi, psi, x


def wrap(angle):
    return (angle + math.pi) % (2 * math.pi) - math.pi


@pytest.mark.parametrize('offset', [-0.02, -0.008, 0.0, 0.012, 0.022])
@pytest.mark.parametrize('input_angle', np.linspace(-3.1, 3.1, 7))
@pytest.mark.parametrize('geometry', [PAPER, PHASED], ids=['paper', 'phased'])
def test_positions_match_vector_loop_solver(geometry, offset, input_angle):
    phi, psi, x = loop_closure_positions(geometry, offset, input_angle)
    got = kin.state(geometry, offset, input_angle, 1.0)
    assert wrap(got.flywheel_angle - phi) == pytest.approx(0.0, abs=1e-10)
    assert got.lever_angle == pytest.approx(psi, abs=1e-10)
    assert got.ram_position == pytest.approx(x, abs=1e-10)


@pytest.mark.parametrize('offset', OFFSETS)
def test_velocities_match_paper_equations(offset):
    """Eq. (4) for the flywheel, eq. (8) for the lever, v = H w_arm / cos^2(psi)."""
    r1, r, h, height = 0.025, 0.0505, 0.113, 0.2
    theta = np.linspace(-math.pi, math.pi, 101)
    input_speed = 3.7
    omega2 = input_speed * r1 * (r1 + offset * np.sin(theta)) / (
        r1 ** 2 + offset ** 2 + 2 * r1 * offset * np.sin(theta))
    got = kin.state(PAPER, offset, theta, input_speed)
    sin_c = np.sin(got.flywheel_angle)
    omega_arm = -omega2 * r * (r + h * sin_c) / (r ** 2 + h ** 2 + 2 * r * h * sin_c)
    np.testing.assert_allclose(got.flywheel_speed, omega2, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(got.lever_speed, omega_arm, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(got.ram_velocity, height * omega_arm / np.cos(got.lever_angle) ** 2,
                               rtol=1e-12, atol=1e-13)


def five_point_derivative(function, t, step):
    return (-function(t + 2 * step) + 8 * function(t + step) - 8 * function(t - step)
            + function(t - 2 * step)) / (12 * step)


@pytest.mark.parametrize('offset_rate', [0.0, 0.004])
@pytest.mark.parametrize('geometry', [PAPER, PHASED], ids=['paper', 'phased'])
def test_rates_are_time_derivatives_of_positions(geometry, offset_rate):
    """Finite differences along a trajectory with accelerating shaft and a moving offset."""
    speed0, accel, offset0 = 5.0, 3.0, -0.004
    t = np.linspace(0.0, 1.5, 61)

    def trajectory(time):
        return kin.state(geometry, offset0 + offset_rate * time,
                         0.2 + speed0 * time + 0.5 * accel * time ** 2,
                         speed0 + accel * time, accel, offset_rate)

    got = trajectory(t)
    step = 1e-4
    for position, rate in [('flywheel_angle', 'flywheel_speed'), ('lever_angle', 'lever_speed'),
                           ('ram_position', 'ram_velocity'), ('ram_velocity', 'ram_acceleration')]:
        numeric = five_point_derivative(lambda s: getattr(trajectory(s), position), t, step)
        scale = np.max(np.abs(numeric))
        np.testing.assert_allclose(getattr(got, rate), numeric, rtol=0, atol=1e-8 * scale,
                                   err_msg=f'{rate} is not d({position})/dt')


def test_zero_offset_is_the_classic_crank_and_slotted_lever():
    theta = np.linspace(-math.pi, math.pi, 50)
    got = kin.state(PAPER, 0.0, theta, 2.5)
    np.testing.assert_allclose(got.flywheel_speed, 2.5, rtol=1e-15)
    ratio = 0.0505 / 0.113
    classic_tr = (math.pi + 2 * math.asin(ratio)) / (math.pi - 2 * math.asin(ratio))  # eq. 28
    assert kin.time_ratio(PAPER, 0.0) == pytest.approx(classic_tr, rel=1e-14)
    assert kin.time_ratio(PAPER, 0.0) == pytest.approx(1.8367, abs=5e-5)
    assert kin.speed_ratio(PAPER, 0.0) == pytest.approx((0.113 + 0.0505) / (0.113 - 0.0505),
                                                        rel=1e-14)
    assert kin.speed_ratio(PAPER, 0.0) == pytest.approx(2.6160, abs=5e-5)


@pytest.mark.parametrize('coupling_radius', [0.01, 0.025, 0.04])
def test_zero_offset_ratios_do_not_depend_on_coupling_radius(coupling_radius):
    geometry = kin.Geometry(coupling_radius, 0.0505, 0.113)
    assert kin.time_ratio(geometry, 0.0) == pytest.approx(kin.time_ratio(PAPER, 0.0), rel=1e-14)
    assert kin.speed_ratio(geometry, 0.0) == pytest.approx(2.616, rel=1e-14)


def test_textbook_half_ratio_gives_time_ratio_two():
    geometry = kin.Geometry(0.025, 0.06, 0.12)
    assert kin.time_ratio(geometry, 0.0) == pytest.approx(2.0, rel=1e-14)  # 240 / 120 degrees


@pytest.mark.parametrize('offset', OFFSETS + [0.0225, -0.0225])
@pytest.mark.parametrize('geometry', [PAPER, PHASED], ids=['paper', 'phased'])
def test_time_ratio_matches_rk4_of_paper_eq20(geometry, offset):
    assert kin.time_ratio(geometry, offset) == pytest.approx(
        kin.time_ratio_rk4(geometry, offset), rel=1e-9)


@pytest.mark.parametrize('offset', [-0.015, 0.0, 0.01, 0.02])
@pytest.mark.parametrize('input_speed', [2.0, -2.0])
def test_time_ratio_matches_dense_sampling_of_velocity_sign(offset, input_speed):
    samples = 2_000_000
    theta = (np.arange(samples) + 0.5) * (2 * math.pi / samples)
    velocity = kin.state(PAPER, offset, theta, input_speed).ram_velocity
    cutting_fraction = np.count_nonzero(velocity < 0.0) / samples
    expected = cutting_fraction / (1.0 - cutting_fraction)
    assert kin.time_ratio(PAPER, offset, input_speed) == pytest.approx(expected, rel=5e-6)


@pytest.mark.parametrize('offset', OFFSETS)
def test_reverse_running_swaps_the_strokes(offset):
    assert kin.time_ratio(PAPER, offset, -1.0) == pytest.approx(
        1.0 / kin.time_ratio(PAPER, offset, 1.0), rel=1e-14)
    assert kin.speed_ratio(PAPER, offset, -1.0) == pytest.approx(
        1.0 / kin.speed_ratio(PAPER, offset, 1.0), rel=1e-14)
    assert kin.time_ratio(PAPER, 0.0, -1.0) < 1.0


@pytest.mark.parametrize('offset', OFFSETS)
def test_speed_ratio_is_paper_eq25(offset):
    r1, r, h = 0.025, 0.0505, 0.113
    expected = (h + r) * (r1 + offset) / ((h - r) * (r1 - offset))
    assert kin.speed_ratio(PAPER, offset) == pytest.approx(expected, rel=1e-13)
    assert kin.speed_ratio_eq25(PAPER, offset) == pytest.approx(expected, rel=1e-15)


def test_speed_ratio_is_one_at_eq26_offset():
    offset = -0.0505 * 0.025 / 0.113
    assert kin.speed_ratio(PAPER, offset) == pytest.approx(1.0, rel=1e-13)
    assert kin.offset_for_speed_ratio(PAPER, 1.0) == pytest.approx(offset, rel=1e-13)


@pytest.mark.parametrize('target', [0.5, 1.0, 2.616, 5.0, 10.0])
@pytest.mark.parametrize('geometry', [PAPER, PHASED], ids=['paper', 'phased'])
def test_offset_for_speed_ratio_round_trips(geometry, target):
    offset = kin.offset_for_speed_ratio(geometry, target)
    assert kin.speed_ratio(geometry, offset) == pytest.approx(target, rel=1e-10)


@pytest.mark.parametrize('target', [0.6, 1.0, 1.8366, 2.0, 4.0])
def test_offset_for_time_ratio_round_trips(target):
    offset = kin.offset_for_time_ratio(PAPER, target)
    assert abs(offset) < 0.025
    assert kin.time_ratio(PAPER, offset) == pytest.approx(target, rel=1e-10)
    assert kin.time_ratio_rk4(PAPER, offset) == pytest.approx(target, rel=1e-9)


def test_short_stroke_without_offset_is_not_quick_and_positive_offset_restores_it():
    """The paper's claim: small r gives TR near 1 at delta = 0; delta > 0 restores it."""
    short = kin.Geometry(0.025, 0.005, 0.113)
    assert kin.time_ratio(short, 0.0) < 1.06
    assert kin.time_ratio(short, 0.015) > 1.5


def test_offset_roughly_doubles_or_halves_both_ratios():
    tr0, sr0 = kin.time_ratio(PAPER, 0.0), kin.speed_ratio(PAPER, 0.0)
    assert kin.time_ratio(PAPER, 0.01) > 1.7 * tr0
    assert kin.time_ratio(PAPER, -0.015) < 0.5 * tr0
    assert kin.speed_ratio(PAPER, 0.01) > 2 * sr0
    assert kin.speed_ratio(PAPER, -0.01) < 0.5 * sr0


def test_ram_stroke_is_independent_of_offset():
    expected = 2 * 0.2 * 0.0505 / math.sqrt(0.113 ** 2 - 0.0505 ** 2)
    assert PAPER.ram_stroke == pytest.approx(expected, rel=1e-15)
    theta = np.linspace(0, 2 * math.pi, 200_001)
    for offset in (-0.015, 0.0, 0.02):
        position = kin.state(PAPER, offset, theta, 1.0).ram_position
        assert position.max() - position.min() == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize('offset', [-0.0224, 0.0, 0.013])
def test_inverse_coupling_round_trips(offset):
    theta = np.linspace(-3.0, 3.0, 41)
    phi = kin.state(PAPER, offset, theta, 1.0).flywheel_angle
    back = kin.input_angle_for_flywheel_angle(PAPER, offset, phi)
    np.testing.assert_allclose(np.angle(np.exp(1j * (back - theta))), 0.0, atol=1e-13)


def test_results_are_finite_everywhere_in_range():
    offsets = np.linspace(-0.0249, 0.0249, 101)
    theta = np.linspace(-10, 10, 1001)[:, None]
    for value in kin.state(PAPER, offsets[None, :], theta, 7.0, 2.0, 0.01):
        assert np.all(np.isfinite(value))


@pytest.mark.parametrize('kwargs, words', [
    ({'coupling_radius': 0.0}, ['coupling_radius', '> 0']),
    ({'crank_radius': -0.01}, ['crank_radius', '> 0']),
    ({'pivot_distance': math.nan}, ['pivot_distance', 'finite']),
    ({'ram_height': math.inf}, ['ram_height', 'finite']),
    ({'crank_radius': 0.2}, ['crank_radius', 'smaller than pivot_distance']),
    ({'crank_phase': 'north'}, ['crank_phase', 'real number']),
])
def test_bad_geometry_is_refused_with_a_readable_message(kwargs, words):
    fields = dict(coupling_radius=0.025, crank_radius=0.0505, pivot_distance=0.113)
    fields.update(kwargs)
    with pytest.raises(kin.KinematicsError) as error:
        kin.Geometry(**fields)
    for word in words:
        assert word in str(error.value)


@pytest.mark.parametrize('offset', [0.025, -0.03, math.nan, math.inf, 'x'])
def test_bad_offset_is_refused_with_the_allowed_range(offset):
    with pytest.raises(kin.KinematicsError) as error:
        kin.time_ratio(PAPER, offset)
    assert 'offset' in str(error.value)


def test_offset_error_states_the_range():
    with pytest.raises(kin.KinematicsError, match=r'\|offset\| < coupling_radius = 0.025 m'):
        kin.state(PAPER, 0.03, 0.0, 1.0)
    with pytest.raises(kin.KinematicsError, match=r'\|offset\| <= 0.0225 m'):
        kin.check_offset(PAPER, 0.023, PAPER.max_safe_offset)


def test_unreachable_targets_state_the_reachable_range():
    with pytest.raises(kin.KinematicsError, match='time_ratio 0.3 is out of reach.*0.41'):
        kin.offset_for_time_ratio(PAPER, 0.3)
    with pytest.raises(kin.KinematicsError, match='speed_ratio must be > 0'):
        kin.offset_for_speed_ratio(PAPER, -1.0)
    with pytest.raises(kin.KinematicsError,
                       match='cutting_speed 0.001 is out of reach.*from 0.25'):
        kin.offset_for_cutting_speed(PAPER, 2 * math.pi, 0.001)
    with pytest.raises(kin.KinematicsError, match='input_speed must be non-zero'):
        kin.time_ratio(PAPER, 0.0, 0.0)
