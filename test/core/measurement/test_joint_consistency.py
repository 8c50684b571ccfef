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
Joint states judged by the closed form (qrm_ros.core.measurement.joint_consistency), sample by
sample.

The check is judged on what it must tell apart: exact samples pass, round-off passes, one
flipped bit in any tied value is caught in that sample (by that value's own check, for a
value the others determine), and another geometry is caught nearly everywhere.
"""

import math
import struct

import numpy as np
import pytest
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.measurement.joint_consistency import (CONSISTENCY_CHECKS, CONSISTENCY_TOLERANCE,
                                                        inconsistent_samples, misplaced_stamps)
from qrm_ros.core.kinematics import state

PAPER = Geometry.paper()


def _samples(geometry=PAPER, count=400):
    """Samples of a run whose offset moves (rate 5 mm/s) through two turns at 2 pi rad/s."""
    time = np.linspace(0.0, 2.0, count)
    angle = (2 * math.pi * time + math.pi) % (2 * math.pi) - math.pi
    offset = -0.005 + 0.005 * time
    rate = np.full(count, 0.005)
    speed = np.full(count, 2 * math.pi)
    moved = state(geometry, offset, angle, speed, 0.0, rate)
    return dict(input_angle=angle, input_speed=speed, offset=offset, offset_rate=rate,
                flywheel_angle=(moved.flywheel_angle + math.pi) % (2 * math.pi) - math.pi,
                flywheel_speed=moved.flywheel_speed, ram_position=moved.ram_position,
                ram_velocity=moved.ram_velocity)


def _flip(value, bit):
    (bits,) = struct.unpack('<Q', struct.pack('<d', value))
    return struct.unpack('<d', struct.pack('<Q', bits ^ (1 << bit)))[0]


def _with_flip(samples, name, index, bit):
    """Flip one bit of one value (a copy of its column); return what the checks say."""
    samples[name] = samples[name].copy()
    samples[name][index] = _flip(float(samples[name][index]), bit)
    return inconsistent_samples(PAPER, **samples)


def _any_check(failed):
    """The samples some check failed."""
    return np.logical_or.reduce(list(failed.values()))


def test_exact_samples_and_round_off_pass():
    samples = _samples()
    assert not any(v.any() for v in inconsistent_samples(PAPER, **samples).values())
    # 1000 times round-off on every value still passes: far below the tolerance.
    noisy = {k: v * (1 + 1e-13) + 1e-14 for k, v in samples.items()}
    assert not any(v.any() for v in inconsistent_samples(PAPER, **noisy).values())
    assert CONSISTENCY_TOLERANCE >= 1e6 * np.finfo(float).eps


# Which check catches a flip of each value (a flip of an input value shows in what depends
# on it: the input angle in the flywheel angle, the input speed in the flywheel speed).
CAUGHT_BY = {'input_angle': 'flywheel_angle', 'offset': 'flywheel_angle',
             'flywheel_angle': 'flywheel_angle', 'ram_position': 'ram_position',
             'input_speed': 'flywheel_speed', 'flywheel_speed': 'flywheel_speed',
             'ram_velocity': 'ram_velocity'}


@pytest.mark.parametrize('name', sorted(CAUGHT_BY))
@pytest.mark.parametrize('bit', [45, 51, 52, 57])
def test_one_flipped_bit_in_any_tied_value_is_caught_in_that_sample_only(name, bit):
    index = 123
    failed = _with_flip(_samples(), name, index, bit)
    # A derived value is caught by its own check; an input value by what depends on it
    # (a huge angle may wrap near the old flywheel angle, never near the old ram position).
    assert failed[CAUGHT_BY[name]][index] or (
        name in ('input_angle', 'input_speed', 'offset')
        and any(caught[index] for caught in failed.values())), (name, bit)
    assert np.flatnonzero(_any_check(failed)).tolist() == [index]


def test_an_offset_beyond_the_coupling_radius_is_its_own_check():
    samples = _samples()
    samples['offset'] = samples['offset'].copy()
    samples['offset'][7] = 0.03
    samples['offset'][8] = math.nan
    failed = inconsistent_samples(PAPER, **samples)
    assert np.flatnonzero(failed['offset']).tolist() == [7, 8]
    assert not any(failed[name].any() for name in CONSISTENCY_CHECKS if name != 'offset')


@pytest.mark.parametrize('field, factor', [('crank_radius', 0.9), ('pivot_distance', 1.05),
                                           ('ram_height', 1.2), ('coupling_radius', 1.1),
                                           ('crank_phase', None)])
def test_a_recording_of_another_geometry_fails_nearly_everywhere(field, factor):
    values = PAPER.as_dict()
    values[field] = 0.1 if factor is None else values[field] * factor
    samples = _samples(Geometry(**values))
    failed = inconsistent_samples(PAPER, **samples)
    assert _any_check(failed).mean() > 0.95


def _stroke_samples(count=400):
    """Samples of a run whose crank radius moves (the stroke screw at 2 mm/s), with the lever."""
    time = np.linspace(0.0, 2.0, count)
    angle = (2 * math.pi * time + math.pi) % (2 * math.pi) - math.pi
    offset = np.full(count, 0.008)
    radius = 0.045 + 0.002 * time
    radius_rate = np.full(count, 0.002)
    speed = np.full(count, 2 * math.pi)
    in_force = Geometry(PAPER.coupling_radius, radius, PAPER.pivot_distance, PAPER.ram_height)
    moved = state(in_force, offset, angle, speed, 0.0, 0.0, radius_rate)
    return dict(input_angle=angle, input_speed=speed, offset=offset,
                offset_rate=np.zeros(count),
                flywheel_angle=(moved.flywheel_angle + math.pi) % (2 * math.pi) - math.pi,
                flywheel_speed=moved.flywheel_speed, ram_position=moved.ram_position,
                ram_velocity=moved.ram_velocity, lever_angle=moved.lever_angle,
                lever_speed=moved.lever_speed, crank_radius=radius,
                crank_radius_rate=radius_rate)


def test_samples_during_a_stroke_change_are_judged_with_the_radius_in_force():
    samples = _stroke_samples()
    assert not any(v.any() for v in inconsistent_samples(PAPER, **samples).values())
    # The same samples judged at the geometry's radius (as if the joint were absent) fail.
    without = dict(samples, crank_radius=None, crank_radius_rate=None)
    assert inconsistent_samples(PAPER, **without)['lever_angle'].mean() > 0.95


# The lever and the crank radius joint: which check catches a flip of each.
CAUGHT_WITH_STROKE = {'lever_angle': 'lever_angle', 'lever_speed': 'lever_speed',
                      'crank_radius': ('crank_radius', 'lever_angle'),
                      'crank_radius_rate': ('crank_radius', 'lever_speed')}


@pytest.mark.parametrize('name', sorted(CAUGHT_WITH_STROKE))
@pytest.mark.parametrize('bit', [45, 51, 52, 57, 62, 63])
def test_one_flipped_bit_in_the_lever_or_the_crank_radius_is_caught(name, bit):
    index = 211
    failed = _with_flip(_stroke_samples(), name, index, bit)
    checks = CAUGHT_WITH_STROKE[name]
    assert any(failed[check][index] for check in np.atleast_1d(checks)), (name, bit)
    assert np.flatnonzero(_any_check(failed)).tolist() == [index]


@pytest.mark.parametrize('radius', [0.0, -0.01, 0.113, 1.0, math.inf])
def test_a_crank_radius_outside_its_range_is_its_own_check(radius):
    samples = _stroke_samples()
    samples['crank_radius'] = samples['crank_radius'].copy()
    samples['crank_radius'][9] = radius
    failed = inconsistent_samples(PAPER, **samples)
    assert np.flatnonzero(failed['crank_radius']).tolist() == [9]
    assert not any(failed[name].any() for name in CONSISTENCY_CHECKS if name != 'crank_radius')


def _steady_shaft(count=300, speed=2 * math.pi):
    time = np.arange(count) * 0.01
    angle = (speed * time + 0.3 + math.pi) % (2 * math.pi) - math.pi
    return time, angle, np.full(count, speed)


# Not whole turns (1 s here): a stamp moved by whole turns leaves the angle right, and only
# the gap it makes tells it (the analysis ends segments at gaps).
@pytest.mark.parametrize('shift', [1e-6, 1e-3, -2e-3, 8.3, -1.37])
def test_one_misplaced_stamp_is_found_and_only_that_sample(shift):
    time, angle, speed = _steady_shaft()
    time[150] += shift
    assert np.flatnonzero(misplaced_stamps(time, angle, speed)).tolist() == [150]


def test_a_pause_a_jump_back_and_a_speed_change_blame_no_sample():
    time, angle, speed = _steady_shaft()
    assert not misplaced_stamps(time, angle, speed).any()
    paused = time.copy()
    paused[100:] += 3.0  # the shaft held while the clock ran: one broken step
    assert not misplaced_stamps(paused, angle, speed).any()
    back = time.copy()
    back[200:] -= 2.0
    assert not misplaced_stamps(back, angle, speed).any()
    changing = speed * (1 + 0.01 * np.arange(speed.size))  # the motor drive: not judged
    assert not misplaced_stamps(time, angle, changing).any()
