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
import sys

import numpy as np
import pytest
from scipy import optimize

from qrm_ros.core import kinematics as kin
from qrm_ros.core import peak_kernel

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


def dense_peak_speeds(geometry, offset, input_speed=1.0, samples=400_001):
    theta = np.linspace(0.0, 2 * math.pi, samples)
    velocity = kin.state(geometry, offset, theta, input_speed).ram_velocity
    return -velocity.min(), velocity.max()


@pytest.fixture(params=['numpy', 'compiled'])
def peak_search(request, monkeypatch):
    """
    Run a test through each peak search: the numpy one, and the compiled one at any size.

    peak_ram_speeds takes the compiled search (qrm_ros.core.peak_kernel) only on sweeps of
    kin._COMPILED_MIN_CONFIGURATIONS or more; the threshold is moved to pick one.
    """
    compiled = request.param == 'compiled'
    if compiled:
        assert kin._compiled_peak_search() is not None, 'numba is a pinned dependency'
    monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS', 1 if compiled else 2 ** 62)
    return request.param


@pytest.mark.parametrize('offset', OFFSETS + [0.0225, -0.0225])
@pytest.mark.parametrize('geometry', [PAPER, PHASED, kin.Geometry(0.025, 0.02, 0.113)],
                         ids=['paper', 'phased', 'short'])
@pytest.mark.usefixtures('peak_search')
def test_peak_speeds_match_dense_sampling(geometry, offset):
    cutting, returning = kin.peak_ram_speeds(geometry, offset, 2.0)
    dense_cut, dense_return = dense_peak_speeds(geometry, offset, 2.0)
    # Dense sampling can only fall short of the true peak, by O(step^2).
    assert dense_cut <= cutting * (1 + 1e-14)
    assert dense_return <= returning * (1 + 1e-14)
    assert cutting == pytest.approx(dense_cut, rel=2e-8)
    assert returning == pytest.approx(dense_return, rel=2e-8)
    assert kin.peak_speed_ratio(geometry, offset, 2.0) == pytest.approx(
        dense_return / dense_cut, rel=5e-8)


@pytest.mark.usefixtures('peak_search')
def test_peak_speed_ratio_equals_mid_stroke_ratio_without_offset():
    assert kin.peak_speed_ratio(PAPER, 0.0) == pytest.approx(kin.speed_ratio(PAPER, 0.0),
                                                             rel=1e-12)


@pytest.mark.usefixtures('peak_search')
def test_peak_speeds_are_found_exactly_not_on_a_grid():
    """At a speed maximum the ram acceleration is zero (to rounding)."""
    cutting, _ = kin.peak_ram_speeds(PAPER, 0.01, 1.0)

    def negative_speed(theta):
        return kin.state(PAPER, 0.01, theta, 1.0).ram_velocity

    best = optimize.minimize_scalar(negative_speed, bounds=(0.5, 3.5), method='bounded',
                                    options={'xatol': 1e-12})
    assert cutting == pytest.approx(-best.fun, rel=1e-13)


def refined_dense_peak_speeds(geometry, offset, input_speed=1.0, samples=200_001):
    """
    Peaks of |ram velocity| from dense input-angle samples, each near-best one refined.

    Every sample interval near the best where the ram acceleration changes sign the way a
    speed maximum does is solved with Brent's method on kin.state's acceleration.
    """
    theta = np.linspace(0.0, 2 * math.pi, samples)
    sampled = kin.state(geometry, offset, theta, 1.0)
    peaks = []
    for sign in (-1.0, 1.0):  # forward running: the cut moves toward -x
        speed, rising = sign * sampled.ram_velocity, sign * sampled.ram_acceleration
        best = speed.max()
        near = speed > best * (1.0 - 1e-2)
        cols = np.nonzero((near[:-1] | near[1:]) & (rising[:-1] > 0.0) & (rising[1:] <= 0.0))[0]

        def acceleration(angle):
            return sign * kin.state(geometry, offset, angle, 1.0).ram_acceleration

        for col in cols:
            angle = theta[col + 1]
            if acceleration(angle) != 0.0:
                angle = optimize.brentq(acceleration, theta[col], angle, xtol=1e-16,
                                        rtol=4 * np.finfo(float).eps)
            best = max(best, sign * kin.state(geometry, offset, angle, 1.0).ram_velocity)
        peaks.append(best * abs(input_speed))
    return tuple(peaks) if input_speed > 0 else tuple(reversed(peaks))


def random_designs(count, seed):
    """Geometries and offsets over the design space, with the edge cases mixed in."""
    rng = np.random.default_rng(seed)
    coupling_radius = rng.uniform(0.01, 0.05, count)
    pivot_distance = rng.uniform(0.05, 0.3, count)
    crank_radius = rng.uniform(0.03, 0.97, count) * pivot_distance
    ram_height = rng.uniform(0.05, 0.5, count)
    phase = np.where(np.arange(count) % 4 == 0, 0.0, rng.uniform(-math.pi, math.pi, count))
    edges = np.array([0.0, 0.9, -0.9, 0.99, -0.99, 0.999, -0.999])
    fraction = np.where(np.arange(count) % 3 == 0, edges[np.arange(count) % len(edges)],
                        rng.uniform(-0.9, 0.9, count))
    geometry = kin.Geometry(coupling_radius, crank_radius, pivot_distance, ram_height, phase)
    return geometry, fraction * coupling_radius


def one_design(geometry, offset, index):
    fields = {name: float(np.asarray(value)[index]) for name, value in geometry.as_dict().items()}
    return kin.Geometry(**fields), float(offset[index])


def lever_only_peak_cutting_speed(geometry):
    """
    Without offset the flywheel turns at the input speed and v = dx/dphi_c.

    For r/h > 1/2 the cut's speed peaks twice, where sin(phi_c) = (h^2 - 2 r^2) / (h r)
    (dv/dphi_c = 0 off mid-stroke), with a minimum, H r / (h + r), at mid-stroke between.
    """
    r, h, height = geometry.crank_radius, geometry.pivot_distance, geometry.ram_height
    sin_peak = (h * h - 2 * r * r) / (h * r)
    return height * r * (h * sin_peak + r) / (h + r * sin_peak) ** 2, height * r / (h + r)


TWO_PEAKED = kin.Geometry(0.025, 0.07, 0.113)


@pytest.mark.parametrize('start', [0.5 * math.pi, 0.72, 0.9],
                         ids=['on-the-minimum', 'step-leaves-bracket', 'convex'])
def test_newton_safeguard_finds_the_peak_not_the_minimum_between(start, monkeypatch):
    """
    A bracket holding two peaks and the minimum between, from starts where plain Newton fails.

    On the mid-stroke minimum dv/dphi_c is zero, so a plain Newton step stays there; from
    0.72 rad its step leaves the bracket; from 0.9 rad (|v| convex) it heads for the minimum.
    The safeguard bisects instead, and every start ends on a peak: numpy's Newton and the
    compiled one (kernel._newton_peak, from the bracket's low end).
    """
    peak, minimum = lever_only_peak_cutting_speed(TWO_PEAKED)
    assert minimum < peak * (1 - 1e-2)
    _, problem = kin._peak_problem(TWO_PEAKED, 0.0)
    speed = kin._newton_peaks(problem, -1.0, np.array([start]), np.array([0.2]),
                              np.array([math.pi - 0.2]))
    assert abs(speed[0]) == pytest.approx(peak, rel=1e-14)
    r1, r, h, height = (getattr(TWO_PEAKED, name) for name in (
        'coupling_radius', 'crank_radius', 'pivot_distance', 'ram_height'))
    constants = (r1, r, h, height, 1.0, 0.0, 0.0, r1 * r1)
    _, root = peak_kernel._newton_peak(
        -1.0, 0.2, math.sin(0.2), math.cos(0.2), start, math.pi - 0.2,
        kin._NEWTON_ANGLE_TOLERANCE, kin._BRACKET_RESOLUTION, kin._NEWTON_MAX_STEPS,
        *constants)
    speed_at_root = peak_kernel._velocity(math.sin(root), math.cos(root), *constants)
    assert abs(speed_at_root) == pytest.approx(peak, rel=1e-14)
    for search in ('numpy', 'compiled'):
        monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS',
                            1 if search == 'compiled' else 2 ** 62)
        cutting, _ = kin.peak_ram_speeds(TWO_PEAKED, 0.0)
        assert cutting == pytest.approx(peak, rel=1e-14), search


@pytest.mark.parametrize('crank_ratio, offset_ratio, phase', [
    (0.14206573443226594, 0.8242592522333362, 2.358138615954723),
    (0.10835303135629527, 0.7495935937551267, 0.5028187362287926),
    (0.5088495575221239, 0.0, 2.56),  # r/h just above 1/2: twin peaks around a minimum
])
@pytest.mark.usefixtures('peak_search')
def test_peaks_that_fewer_samples_missed(crank_ratio, offset_ratio, phase):
    """
    Designs where a peak was once missed.

    The first two with 16 and 8 samples per stroke (two close peaks in one sample interval),
    the last before Newton's steps were limited to where |v| is concave (it settled on the
    minimum between the twin peaks, 1e-5 low).
    """
    geometry = kin.Geometry(0.025, crank_ratio * 0.113, 0.113, 0.2, phase)
    np.testing.assert_allclose(kin.peak_ram_speeds(geometry, offset_ratio * 0.025),
                               refined_dense_peak_speeds(geometry, offset_ratio * 0.025),
                               rtol=1e-12)


def test_compiled_search_matches_the_numpy_search_over_many_random_designs(monkeypatch):
    """10^4 designs (offsets up to 0.999 r1, both running directions): the same peaks."""
    geometry, offsets = random_designs(10_000, 8)
    input_speed = np.where(np.arange(10_000) % 2 == 0, 2.0, -2.0)
    _, flat = kin._flat_design(geometry, offsets)
    compiled = peak_kernel.peak_speeds(*flat, *kin._PEAK_SAMPLES, kin._NEWTON_ANGLE_TOLERANCE,
                                       kin._BRACKET_RESOLUTION, kin._NEWTON_MAX_STEPS)
    np.testing.assert_allclose(compiled, kin._peak_speeds_numpy(geometry, offsets), rtol=1e-12)
    by_numpy = kin.peak_ram_speeds(geometry, offsets, input_speed)
    monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS', 1)
    np.testing.assert_allclose(kin.peak_ram_speeds(geometry, offsets, input_speed), by_numpy,
                               rtol=1e-12)


def long_double_peak_speeds(geometry, offset, samples=20_001):
    """
    Forward peak speeds in extended precision: v = dx/dphi_c times the paper's eq. (20).

    x = H tan(psi) with tan(psi) = r cos(phi_c) / (h + r sin(phi_c)), differentiated by hand;
    dense crank-angle samples per stroke, then every local maximum near the best refined by
    golden-section search, all in numpy's long double (80-bit here).
    """
    ld = np.longdouble
    r1, r, h, height, phase = (ld(getattr(geometry, name)) for name in geometry.field_names())
    d = ld(offset)

    def speed(angle):
        sin_c = np.sin(angle)
        flywheel = angle - phase
        sin_f, cos_f = np.sin(flywheel), np.cos(flywheel)
        pin = d * sin_f + np.sqrt(r1 * r1 - (d * cos_f) ** 2)
        coupling = (r1 * r1 - d * d + d * pin * sin_f) / (pin * pin)
        return -height * r * (h * sin_c + r) / (h + r * sin_c) ** 2 * coupling

    gap, half_turn = np.arcsin(r / h), ld(math.pi)
    golden = (np.sqrt(ld(5)) - 1) / 2
    peaks = []
    strokes = ((-1, -gap, half_turn + gap), (1, half_turn + gap, 2 * half_turn - gap))
    for sign, start, end in strokes:
        angles = start + (end - start) * np.arange(samples, dtype=ld) / (samples - 1)
        values = sign * speed(angles)
        best = values.max()
        inner = np.nonzero((values[1:-1] >= values[:-2]) & (values[1:-1] >= values[2:])
                           & (values[1:-1] > best * (1 - 1e-3)))[0] + 1
        for k in inner:
            low, high = angles[k - 1], angles[k + 1]
            for _ in range(120):
                left, right = high - golden * (high - low), low + golden * (high - low)
                if sign * speed(left) < sign * speed(right):
                    low = left
                else:
                    high = right
            best = max(best, sign * speed((low + high) / 2))
        peaks.append(float(best))
    return peaks


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason='long double is double here')
def test_peaks_match_an_extended_precision_search(monkeypatch):
    """
    Designs with offsets of 0.999 r1 and ordinary ones: exact to a few ulps, not 1e-12.

    Both searches (the threshold moved for the compiled one) against one reference each.
    """
    geometry, offsets = random_designs(400, 30)
    fraction = offsets / geometry.coupling_radius
    edge = np.nonzero(np.abs(np.abs(fraction) - 0.999) < 1e-9)[0][:20]
    for index in list(edge) + list(range(10)):
        single, offset = one_design(geometry, offsets, index)
        expected = long_double_peak_speeds(single, offset)
        for threshold in (2 ** 62, 1):
            monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS', threshold)
            np.testing.assert_allclose(
                kin.peak_ram_speeds(single, offset), expected, rtol=2e-14,
                err_msg=f'design {index}: {single}, offset {offset}, threshold {threshold}')


def test_large_sweeps_take_the_compiled_search(monkeypatch):
    calls = []

    def spy(*args):
        calls.append(args[0].size)
        return peak_kernel.peak_speeds(*args)

    monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS', 300)
    monkeypatch.setattr(kin, '_compiled_peak_search', lambda: spy)
    offsets = np.linspace(-0.02, 0.02, 300)
    numpy_peaks = kin._peak_speeds_numpy(PAPER, offsets)
    np.testing.assert_allclose(kin.peak_ram_speeds(PAPER, offsets), numpy_peaks, rtol=1e-13)
    np.testing.assert_allclose(kin.peak_ram_speeds(PAPER, offsets[:-1]),
                               [p[:-1] for p in numpy_peaks], rtol=1e-13)
    assert calls == [300]


def test_without_numba_large_sweeps_take_the_numpy_search(monkeypatch):
    import qrm_ros.core
    monkeypatch.delattr(qrm_ros.core, 'peak_kernel', raising=False)
    monkeypatch.setitem(sys.modules, 'qrm_ros.core.peak_kernel', None)  # import fails
    assert kin._compiled_peak_search() is None
    monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS', 10)
    offsets = np.linspace(-0.02, 0.02, 20)
    np.testing.assert_array_equal(kin.peak_ram_speeds(PAPER, offsets),
                                  kin._peak_speeds_numpy(PAPER, offsets))


def test_rotation_series_match_sin_and_cos():
    """The compiled search's rotations by series and by sin and cos: alike to rounding."""
    rng = np.random.default_rng(9)
    edges = [0.0, 0.3, -0.3, 1e-3, -1e-3, 2.0]
    for delta in np.concatenate([rng.uniform(-0.3, 0.3, 500), rng.uniform(-1e-3, 1e-3, 500),
                                 rng.uniform(-1e-9, 1e-9, 50), edges]):
        angle = rng.uniform(-4.0, 7.0)
        rotated = peak_kernel._rotate(math.sin(angle), math.cos(angle), delta)
        np.testing.assert_allclose(rotated, (math.sin(angle + delta), math.cos(angle + delta)),
                                   rtol=0, atol=1e-15, err_msg=f'delta {delta}')


def test_speed_rise_has_the_sign_of_the_speed_slope():
    """The peak search's cheap sample test against central differences of |v| from state()."""
    geometry, offsets = random_designs(200, 5)
    rng = np.random.default_rng(6)
    start, end = kin.reversal_flywheel_angles(geometry)
    fraction = rng.uniform(0.01, 0.99, 200)
    on_return = np.arange(200) % 2 == 1
    flywheel_angle = np.where(on_return, end + fraction * (start + 2 * math.pi - end),
                              start + fraction * (end - start))
    step = 1e-6

    def speed(angle):
        theta = kin.input_angle_for_flywheel_angle(geometry, offsets, angle)
        return np.abs(kin.state(geometry, offsets, theta, 1.0).ram_velocity)

    slope = (speed(flywheel_angle + step) - speed(flywheel_angle - step)) / (2 * step)
    _, problem = kin._peak_problem(geometry, offsets)
    rise = kin._speed_rise(flywheel_angle + geometry.crank_phase, problem)
    clear = np.abs(slope) > 1e-6 * speed(flywheel_angle)
    assert np.count_nonzero(clear) > 150
    np.testing.assert_array_equal(np.sign(rise[clear]) * np.where(on_return, -1, 1),
                                  np.sign(slope[clear]))


@pytest.mark.parametrize('seed', [1, 2])
def test_peak_speeds_match_refined_dense_sampling_over_random_designs(seed, monkeypatch):
    """
    Vectorised peaks against refined dense sampling, design by design, both directions.

    Both searches (numpy's, and the compiled one the threshold is moved for) against the
    one dense reference; scalar calls take the numpy search.
    """
    geometry, offsets = random_designs(40, seed)
    input_speed = np.where(np.arange(40) % 2 == 0, 3.0, -3.0)
    cutting, returning = kin.peak_ram_speeds(geometry, offsets, input_speed)
    monkeypatch.setattr(kin, '_COMPILED_MIN_CONFIGURATIONS', 1)
    compiled = kin.peak_ram_speeds(geometry, offsets, input_speed)
    monkeypatch.undo()
    assert cutting.shape == returning.shape == compiled[0].shape == (40,)
    for index in range(40):
        single, offset = one_design(geometry, offsets, index)
        expected = refined_dense_peak_speeds(single, offset, input_speed[index])
        message = f'design {index}: {single}, offset {offset}'
        np.testing.assert_allclose((cutting[index], returning[index]), expected, rtol=1e-12,
                                   err_msg=message)
        np.testing.assert_allclose((compiled[0][index], compiled[1][index]), expected,
                                   rtol=1e-12, err_msg=message)
        np.testing.assert_allclose(kin.peak_ram_speeds(single, offset, input_speed[index]),
                                   (cutting[index], returning[index]), rtol=1e-14)


@pytest.mark.parametrize('seed', [3, 4])
@pytest.mark.usefixtures('peak_search')
def test_peak_speeds_match_the_bracketing_method_within_the_safe_offset(seed):
    """The previous method (48 samples per stroke, Chandrupatla) as the reference."""
    geometry, offsets = random_designs(400, seed)
    offsets = np.clip(offsets, -geometry.max_safe_offset, geometry.max_safe_offset)
    for input_speed, forward in ((2.0, slice(None)), (-2.0, slice(None, None, -1))):
        expected = np.multiply(kin._peak_speeds_bracketing(geometry, offsets), 2.0)[forward]
        np.testing.assert_allclose(kin.peak_ram_speeds(geometry, offsets, input_speed),
                                   expected, rtol=1e-12)


@pytest.mark.parametrize('target', [0.26, 0.3, 0.388, 0.6, 1.5])
@pytest.mark.usefixtures('peak_search')
def test_offset_for_cutting_speed_round_trips(target):
    input_speed = 2 * math.pi
    offset = kin.offset_for_cutting_speed(PAPER, input_speed, target)
    cutting, _ = dense_peak_speeds(PAPER, offset, input_speed)
    assert cutting == pytest.approx(target, rel=1e-8)


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


@pytest.mark.usefixtures('peak_search')
def test_vectorised_calls_match_scalar_calls():
    offsets = np.array(OFFSETS)
    for function in (kin.time_ratio, kin.speed_ratio, kin.peak_speed_ratio):
        vector = function(PAPER, offsets)
        assert vector.shape == offsets.shape
        np.testing.assert_allclose(vector, [function(PAPER, d) for d in OFFSETS], rtol=1e-15)
    radii = np.linspace(0.01, 0.1, 7)[:, None]
    sweep = kin.Geometry(0.025, radii, 0.113)
    grid = kin.time_ratio(sweep, offsets[None, :])
    assert grid.shape == (7, len(OFFSETS))
    assert grid[3, 2] == pytest.approx(
        kin.time_ratio(kin.Geometry(0.025, float(radii[3, 0]), 0.113), OFFSETS[2]), rel=1e-15)


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
