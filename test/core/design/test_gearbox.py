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
Gearbox planner against independent routes.

Band ends are checked against the kinematics core at the offsets printed; the usable offsets
against time ratios computed directly; minimality by brute force over geometric gearboxes
with one step fewer, whose reach comes from a dense sampling of the offsets (not from the
planner's band).
"""

import math

import numpy as np
import pytest

from qrm_ros.core.design import gearbox
from qrm_ros.core import kinematics as kin

PAPER = kin.Geometry.paper()
PHASED = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=0.4)


def core_cutting_speed(geometry, definition, offset, input_speed):
    if definition == 'mean':
        return kin.mean_cutting_speed(geometry, offset, input_speed)
    return kin.peak_ram_speeds(geometry, offset, input_speed)[0]


CASES = [
    (PAPER, 'mean', 0.1, 0.5, None, 1.0),
    (PAPER, 'peak', 0.1, 0.5, None, 1.0),
    (PAPER, 'mean', 0.05, 0.8, 0.015, 1.5),
    (PHASED, 'mean', 0.2, 0.3, 0.01, 1.0),
    (PHASED, 'peak', 0.12, 0.9, None, 1.2),
]


@pytest.fixture(scope='module', params=CASES, ids=lambda case: f'{case[1]}-{case[2]}-{case[3]}')
def planned(request):
    geometry, definition, v1, v2, max_offset, min_tr = request.param
    plan = gearbox.plan_gearbox(geometry, v1, v2, definition, max_offset, min_tr)
    return geometry, plan


def test_bands_are_contiguous_ordered_and_cover_the_range(planned):
    _, plan = planned
    steps = plan.steps
    assert steps[0].cutting_speed_min == plan.min_cutting_speed
    assert steps[-1].cutting_speed_max == plan.max_cutting_speed
    for lower, upper in zip(steps, steps[1:]):
        assert lower.cutting_speed_max == upper.cutting_speed_min
        assert lower.input_speed < upper.input_speed
    for step in steps:
        assert step.cutting_speed_min < step.cutting_speed_max


def test_input_speeds_are_a_geometric_progression(planned):
    _, plan = planned
    speeds = np.array([step.input_speed for step in plan.steps])
    np.testing.assert_allclose(speeds[1:] / speeds[:-1], plan.progression_ratio, rtol=1e-12)
    assert plan.progression_ratio <= plan.band_ratio * (1 + 1e-12)
    assert plan.progression_ratio ** len(speeds) == pytest.approx(
        plan.max_cutting_speed / plan.min_cutting_speed, rel=1e-12)


def test_band_ends_are_the_core_cutting_speed_at_the_printed_offsets(planned):
    geometry, plan = planned
    for step in plan.steps:
        at_ends = core_cutting_speed(geometry, plan.definition,
                                     np.array([step.offset_at_min, step.offset_at_max]),
                                     step.input_speed)
        np.testing.assert_allclose(at_ends, [step.cutting_speed_min, step.cutting_speed_max],
                                   rtol=1e-11)


def test_offsets_stay_within_the_limits(planned):
    geometry, plan = planned
    limit = geometry.max_safe_offset if plan.max_offset is None else plan.max_offset
    for step in plan.steps:
        offsets = np.array([step.offset_at_min, step.offset_at_max])
        assert np.all(np.abs(offsets) <= limit)
        assert np.all(kin.time_ratio(geometry, offsets) >= plan.min_time_ratio * (1 - 1e-12))


def test_usable_offsets_are_where_the_time_ratio_allows(planned):
    geometry, plan = planned
    grid = np.linspace(-plan.max_offset, plan.max_offset, 20001)
    allowed = grid[kin.time_ratio(geometry, grid) >= plan.min_time_ratio]
    assert plan.offsets.offset_min == pytest.approx(allowed.min(), abs=3 * np.diff(grid)[0])
    assert plan.offsets.offset_max == pytest.approx(allowed.max(), abs=3 * np.diff(grid)[0])


def sampled_reach(geometry, definition, plan):
    """Slowest and fastest cutting speed per input speed over densely sampled offsets."""
    grid = np.linspace(plan.offsets.offset_min, plan.offsets.offset_max, 4001)
    values = core_cutting_speed(geometry, definition, grid, 1.0)
    return values.min(), values.max()


def test_band_matches_dense_sampling_of_the_offsets(planned):
    geometry, plan = planned
    slowest, fastest = sampled_reach(geometry, plan.definition, plan)
    assert plan.offsets.slowest_per_input_speed <= slowest * (1 + 1e-12)
    assert plan.offsets.fastest_per_input_speed >= fastest * (1 - 1e-12)
    assert plan.offsets.slowest_per_input_speed == pytest.approx(slowest, rel=1e-6)
    assert plan.offsets.fastest_per_input_speed == pytest.approx(fastest, rel=1e-6)


def covers(input_speeds, slowest, fastest, wanted):
    """Does some step reach each wanted speed with an offset in the sampled reach?"""
    per_unit = wanted[:, None] / np.asarray(input_speeds)[None, :]
    return np.all(np.any((per_unit >= slowest) & (per_unit <= fastest), axis=1))


@pytest.mark.parametrize('geometry, definition, v1, v2, max_offset, min_tr', [
    (PAPER, 'mean', 0.1, 0.5, None, 1.0),
    (PAPER, 'mean', 0.1, 0.3, 0.01, 1.0),
    (PAPER, 'peak', 0.1, 0.5, None, 1.0),
    (PHASED, 'mean', 0.2, 0.3, 0.01, 1.0),
])
def test_one_step_fewer_is_impossible_by_brute_force(geometry, definition, v1, v2, max_offset,
                                                     min_tr):
    plan = gearbox.plan_gearbox(geometry, v1, v2, definition, max_offset, min_tr)
    slowest, fastest = sampled_reach(geometry, definition, plan)
    slowest, fastest = slowest * (1 - 1e-6), fastest * (1 + 1e-6)  # generous to the rival
    wanted = np.geomspace(v1, v2, 200)
    assert covers([s.input_speed for s in plan.steps], slowest * 0.999, fastest * 1.001, wanted)
    fewer = len(plan.steps) - 1
    if fewer == 0:
        return
    # Every geometric gearbox with one step fewer: lowest speed and ratio on a fine grid.
    lowest = np.geomspace(v1 / fastest / 1.2, v1 / slowest * 1.2, 200)
    ratios = np.geomspace(1.0001, (v2 / v1) * 2, 200) if fewer > 1 else np.array([1.0])
    for ratio in ratios:
        for first in lowest:
            speeds = first * ratio ** np.arange(fewer)
            assert not covers(speeds, slowest, fastest, wanted), (first, ratio)


@pytest.mark.parametrize('v1, v2', [(0.1, 0.5), (0.05, 0.8), (0.2, 0.21)])
@pytest.mark.parametrize('ratio', gearbox.STANDARD_PROGRESSION_RATIOS)
def test_conventional_gearbox_keeps_every_speed_within_its_shortfall(v1, v2, ratio):
    box = gearbox.conventional_gearbox(PAPER, 'mean', v1, v2, ratio)
    assert box.max_shortfall == pytest.approx(1 - 1 / ratio, rel=1e-15)
    speeds = np.array(box.cutting_speeds)
    np.testing.assert_allclose(speeds[1:] / speeds[:-1], ratio, rtol=1e-12)
    np.testing.assert_allclose(kin.mean_cutting_speed(PAPER, 0.0, np.array(box.input_speeds)),
                               speeds, rtol=1e-12)
    wanted = np.geomspace(v1, v2, 2000)

    def worst_shortfall(step_speeds):
        # The fastest step not above each wanted speed (none: nothing can cut it).
        index = np.searchsorted(step_speeds, wanted * (1 + 1e-12), side='right') - 1
        if np.any(index < 0):
            return 1.0
        return np.max(1 - step_speeds[index] / wanted)

    assert worst_shortfall(speeds) <= box.max_shortfall + 1e-12
    # One step fewer, from any start at or below v1, leaves some wanted speed short.
    if box.step_count > 1:
        for first in np.geomspace(v1 / ratio, v1, 200):
            fewer = first * ratio ** np.arange(box.step_count - 1)
            assert worst_shortfall(fewer) > box.max_shortfall + 1e-9


def test_step_count_is_exact_at_the_band_ratio_boundary():
    free = gearbox.plan_gearbox(PAPER, 0.1, 0.2)
    q = free.band_ratio
    for count in (1, 2, 4):
        plan = gearbox.plan_gearbox(PAPER, 0.1, 0.1 * q ** count)
        assert len(plan.steps) == count
        # Every band then spans the whole reach: the offsets sit at the usable limits.
        for step in plan.steps:
            assert step.offset_at_min == pytest.approx(plan.offsets.offset_at_slowest, abs=1e-9)
            assert step.offset_at_max == pytest.approx(plan.offsets.offset_at_fastest, abs=1e-9)
        assert len(gearbox.plan_gearbox(PAPER, 0.1, 0.1 * q ** count * 1.001).steps) == count + 1


def test_fewest_steps_matches_counting():
    for range_ratio in (1.5, 2.0, 5.0, 17.0):
        for step_ratio in (1.12, 1.26, 2.0, 3.0):
            count = gearbox.fewest_steps(range_ratio, step_ratio)
            assert step_ratio ** count >= range_ratio
            assert count == 1 or step_ratio ** (count - 1) < range_ratio
    assert gearbox.fewest_steps(2.0 ** 3, 2.0) == 3


@pytest.mark.parametrize('definition, max_offset, min_time_ratio, band_ratio, count', [
    ('mean', None, 1.0, 1.8907, 3),
    ('mean', None, 1.5, 1.5756, 4),
    ('mean', None, 1.8367, 1.4601, 5),
    ('mean', 0.01, 1.0, 1.4387, 5),
    ('peak', None, 1.0, 3.0903, 2),
])
def test_the_readme_worked_case(definition, max_offset, min_time_ratio, band_ratio, count):
    plan = gearbox.plan_gearbox(PAPER, 0.1, 0.5, definition, max_offset, min_time_ratio)
    assert plan.band_ratio == pytest.approx(band_ratio, abs=5e-5)
    assert len(plan.steps) == count
    by_ratio = {box.progression_ratio: box.step_count for box in plan.conventional}
    assert by_ratio == {1.12: 15, 1.26: 7, 1.41: 5, 1.58: 4, 2.0: 3}
    shortfalls = [round(box.max_shortfall * 100, 1) for box in plan.conventional]
    assert shortfalls == [10.7, 20.6, 29.1, 36.7, 50.0]


def test_the_readme_costs_of_the_three_step_plan():
    plan = gearbox.plan_gearbox(PAPER, 0.1, 0.5)
    fast_end, slow_end = plan.steps[0].offset_at_max, plan.steps[0].offset_at_min
    assert fast_end * 1e3 == pytest.approx(-10.43, abs=5e-3)
    assert slow_end * 1e3 == pytest.approx(19.86, abs=5e-3)
    assert kin.time_ratio(PAPER, fast_end) == pytest.approx(1.11, abs=5e-3)
    assert plan.offsets.offset_min * 1e3 == pytest.approx(-12.49, abs=5e-3)
    # Peak flywheel speed over input speed is r1 / (r1 - offset), at input angle -90 degrees.
    ratio = PAPER.coupling_radius / (PAPER.coupling_radius - slow_end)
    assert ratio == pytest.approx(4.86, abs=5e-3)
    theta = np.linspace(-math.pi, math.pi, 20001)
    assert np.max(kin.state(PAPER, slow_end, theta, 1.0).flywheel_speed) == pytest.approx(
        ratio, rel=1e-6)
    assert kin.mean_cutting_speed(PAPER, 0.0, 1.0) == pytest.approx(0.049119, abs=5e-7)
    assert PAPER.ram_stroke * 1e3 == pytest.approx(199.83, abs=5e-3)


@pytest.mark.parametrize('kwargs, words', [
    (dict(min_cutting_speed=0.5, max_cutting_speed=0.1),
     'min_cutting_speed (0.5 m/s) must be below max_cutting_speed (0.1 m/s)'),
    (dict(min_cutting_speed=0.2, max_cutting_speed=0.2), 'must be below max_cutting_speed'),
    (dict(min_cutting_speed=0.0), 'min_cutting_speed must be one number > 0 m/s'),
    (dict(max_cutting_speed=-1.0), 'max_cutting_speed must be one number > 0 m/s'),
    (dict(min_cutting_speed=float('nan')), 'min_cutting_speed must be finite'),
    (dict(definition='median'), "definition must be one of mean, peak, got 'median'"),
    (dict(max_offset=0.025), 'max_offset must be >= 0 and < coupling_radius = 0.025 m'),
    (dict(max_offset=-0.001), 'max_offset must be >= 0'),
    (dict(max_offset=0.0), 'leave one mean cutting speed per step'),
    (dict(max_offset=1e-12), 'leave one mean cutting speed per step'),
    (dict(max_offset=1e-6), 'more than 100 steps would be needed'),
    (dict(min_time_ratio=30.0), 'min_time_ratio 30 is out of reach: offsets with |offset| <= '
                                '0.0225 m give TR from 0.537'),
    (dict(min_time_ratio=0.0), 'min_time_ratio must be one number > 0'),
])
def test_bad_requests_are_refused_with_reasons(kwargs, words):
    arguments = dict(geometry=PAPER, min_cutting_speed=0.1, max_cutting_speed=0.5)
    arguments.update(kwargs)
    with pytest.raises(kin.KinematicsError) as error:
        gearbox.plan_gearbox(**arguments)
    assert words in str(error.value)


def test_offset_without_effect_is_refused():
    sideways = kin.Geometry(0.025, 0.0505, 0.113, 0.2, crank_phase=math.pi / 2)
    with pytest.raises(kin.KinematicsError, match='leave one mean cutting speed per step'):
        gearbox.plan_gearbox(sideways, 0.1, 0.5)
