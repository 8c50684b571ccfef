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
The peak-speed search (numpy and compiled) against dense sampling and independent methods.

Each expected value comes from a different route than the code under test: brute-force
dense sampling of state(), refined and extended-precision searches, the previous bracketing
method, or the two searches held against each other.
"""

import math
import sys

import numpy as np
import pytest
from scipy import optimize

from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics import peak_kernel, peak_speeds
from qrm_ros.core.numerics.kernel_tools import rotate
from qrm_ros.core.kinematics.peak_speeds_bracketing import peak_speeds_bracketing

PAPER = kin.Geometry.paper()
OFFSETS = [-0.02, -0.015, -0.0111725663716814, -0.005, 0.0, 0.005, 0.01, 0.015, 0.02]
PHASED = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=0.4)


def dense_peak_speeds(geometry, offset, input_speed=1.0, samples=400_001):
    theta = np.linspace(0.0, 2 * math.pi, samples)
    velocity = kin.state(geometry, offset, theta, input_speed).ram_velocity
    return -velocity.min(), velocity.max()


@pytest.fixture(params=['numpy', 'compiled'])
def peak_search(request, monkeypatch):
    """
    Run a test through each peak search: the numpy one, and the compiled one at any size.

    peak_ram_speeds takes the compiled search (qrm_ros.core.kinematics.peak_kernel) only on sweeps
    of peak_speeds.COMPILED_MIN_CONFIGURATIONS or more; the threshold is moved to pick one.
    """
    compiled = request.param == 'compiled'
    if compiled:
        assert peak_speeds.compiled_peak_search() is not None, 'numba is a pinned dependency'
    monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS', 1 if compiled else 2 ** 62)
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
    compiled one (peak_kernel.newton_peak, from the bracket's low end).
    """
    peak, minimum = lever_only_peak_cutting_speed(TWO_PEAKED)
    assert minimum < peak * (1 - 1e-2)
    _, problem = peak_speeds.peak_problem(TWO_PEAKED, 0.0)
    speed = peak_speeds.newton_peaks(problem, -1.0, np.array([start]), np.array([0.2]),
                                     np.array([math.pi - 0.2]))
    assert abs(speed[0]) == pytest.approx(peak, rel=1e-14)
    r1, r, h, height = (getattr(TWO_PEAKED, name) for name in (
        'coupling_radius', 'crank_radius', 'pivot_distance', 'ram_height'))
    constants = (r1, r, h, height, 1.0, 0.0, 0.0, r1 * r1)
    _, root = peak_kernel.newton_peak(
        -1.0, 0.2, math.sin(0.2), math.cos(0.2), start, math.pi - 0.2,
        peak_speeds.NEWTON_ANGLE_TOLERANCE, peak_speeds.BRACKET_RESOLUTION,
        peak_speeds.NEWTON_MAX_STEPS, *constants)
    speed_at_root = peak_kernel.velocity(math.sin(root), math.cos(root), *constants)
    assert abs(speed_at_root) == pytest.approx(peak, rel=1e-14)
    for search in ('numpy', 'compiled'):
        monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS',
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
    _, flat = peak_speeds.flat_design(geometry, offsets)
    compiled = peak_kernel.peak_speeds(
        *flat, *peak_speeds.PEAK_SAMPLES, peak_speeds.NEWTON_ANGLE_TOLERANCE,
        peak_speeds.BRACKET_RESOLUTION, peak_speeds.NEWTON_MAX_STEPS)
    np.testing.assert_allclose(compiled, peak_speeds.peak_speeds_numpy(geometry, offsets),
                               rtol=1e-12)
    by_numpy = kin.peak_ram_speeds(geometry, offsets, input_speed)
    monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS', 1)
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
            monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS', threshold)
            np.testing.assert_allclose(
                kin.peak_ram_speeds(single, offset), expected, rtol=2e-14,
                err_msg=f'design {index}: {single}, offset {offset}, threshold {threshold}')


def test_large_sweeps_take_the_compiled_search(monkeypatch):
    calls = []

    def spy(*args):
        calls.append(args[0].size)
        return peak_kernel.peak_speeds(*args)

    monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS', 300)
    monkeypatch.setattr(peak_speeds, 'compiled_peak_search', lambda: spy)
    offsets = np.linspace(-0.02, 0.02, 300)
    numpy_peaks = peak_speeds.peak_speeds_numpy(PAPER, offsets)
    np.testing.assert_allclose(kin.peak_ram_speeds(PAPER, offsets), numpy_peaks, rtol=1e-13)
    np.testing.assert_allclose(kin.peak_ram_speeds(PAPER, offsets[:-1]),
                               [p[:-1] for p in numpy_peaks], rtol=1e-13)
    assert calls == [300]


def test_without_numba_large_sweeps_take_the_numpy_search(monkeypatch):
    import qrm_ros.core.kinematics
    monkeypatch.delattr(qrm_ros.core.kinematics, 'peak_kernel', raising=False)
    monkeypatch.setitem(sys.modules, 'qrm_ros.core.kinematics.peak_kernel', None)  # import fails
    assert peak_speeds.compiled_peak_search() is None
    monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS', 10)
    offsets = np.linspace(-0.02, 0.02, 20)
    np.testing.assert_array_equal(kin.peak_ram_speeds(PAPER, offsets),
                                  peak_speeds.peak_speeds_numpy(PAPER, offsets))


def test_rotation_series_match_sin_and_cos():
    """The compiled search's rotations by series and by sin and cos: alike to rounding."""
    rng = np.random.default_rng(9)
    edges = [0.0, 0.3, -0.3, 1e-3, -1e-3, 2.0]
    for delta in np.concatenate([rng.uniform(-0.3, 0.3, 500), rng.uniform(-1e-3, 1e-3, 500),
                                 rng.uniform(-1e-9, 1e-9, 50), edges]):
        angle = rng.uniform(-4.0, 7.0)
        rotated = rotate(math.sin(angle), math.cos(angle), delta)
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
    _, problem = peak_speeds.peak_problem(geometry, offsets)
    rise = peak_speeds.speed_rise(flywheel_angle + geometry.crank_phase, problem)
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
    monkeypatch.setattr(peak_speeds, 'COMPILED_MIN_CONFIGURATIONS', 1)
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
        expected = np.multiply(peak_speeds_bracketing(geometry, offsets), 2.0)[forward]
        np.testing.assert_allclose(kin.peak_ram_speeds(geometry, offsets, input_speed),
                                   expected, rtol=1e-12)


@pytest.mark.parametrize('target', [0.26, 0.3, 0.388, 0.6, 1.5])
@pytest.mark.usefixtures('peak_search')
def test_offset_for_cutting_speed_round_trips(target):
    input_speed = 2 * math.pi
    offset = kin.offset_for_cutting_speed(PAPER, input_speed, target)
    cutting, _ = dense_peak_speeds(PAPER, offset, input_speed)
    assert cutting == pytest.approx(target, rel=1e-8)


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
