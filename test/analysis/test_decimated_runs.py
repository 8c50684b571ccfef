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
The sampling bounds the analysis states, checked against the true error of decimated runs.

A run sampled at 100 Hz (synthetic, and the golden logs recorded by the node) is decimated
to 10 Hz and 2.5 Hz (60 rpm: 10 and 2.5 samples per input revolution); every figure's
stated bound must cover its true error (measured against the closed form), and a figure
without a bound, or with one above 1e-3 relative, must be warned about. At 100 Hz every
bound is below 1e-3 and nothing is warned.
"""

import math
import os

import numpy as np
import pytest

from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import report
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.sampling_bounds import BOUNDED_FIGURES, SUPPORTED_RELATIVE_ERROR
from repo_paths import TEST_DATA
from synthetic_run import samples_for

PAPER = kin.Geometry.paper()
# The theory's own accuracy (its integrals and root finding): far below any sampling bound.
THEORY_TOLERANCE = 1e-9
GOLDEN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')


def _decimated(samples, every):
    return recorded_run.Samples(*(None if field is None else field[::every]
                                  for field in samples))


def _covered(row):
    """Check each figure's bound covers its true error; return the figures left unbounded."""
    unbounded = []
    for name in BOUNDED_FIGURES:
        measured, theory = row[f'{name}_measured'], row[f'{name}_theory']
        if measured is None or theory is None:
            continue
        bound = row[f'{name}_sampling_bound']
        if bound is None:
            unbounded.append(name)
            continue
        assert abs(measured - theory) <= bound + THEORY_TOLERANCE * abs(theory), (
            name, row['offset'], measured, theory, bound)
    return unbounded


def _warned(analysis):
    return '\n'.join(report.unsupported_by_sampling(analysis))


@pytest.mark.parametrize('offset', [-0.015, -0.008, 0.0, 0.01, 0.015])
@pytest.mark.parametrize('every', [1, 10, 40])
def test_stated_bound_covers_the_true_error_of_a_decimated_run(offset, every):
    samples = _decimated(samples_for([offset], hold=12.0, rate=100.0), every)
    analysis = measurement.analyse(recorded_run.Recording('run', PAPER, samples, None))
    (row,) = analysis.rows
    unbounded = _covered(row)
    warned = _warned(analysis)
    for name in BOUNDED_FIGURES:
        if row[f'{name}_measured'] is None:
            continue
        relative = report.sampling_relative_bound(row, name)
        if relative is None or relative > SUPPORTED_RELATIVE_ERROR:
            assert report.FIGURE_WORDS[name] + ' is not supported' in warned, name
    if every == 1:
        assert not unbounded and not warned
        for name in BOUNDED_FIGURES:
            relative = report.sampling_relative_bound(row, name)
            assert relative is None or relative < SUPPORTED_RELATIVE_ERROR


@pytest.mark.parametrize('every', [1, 10, 40])
def test_stated_bound_covers_the_true_error_of_a_decimated_golden_log(every):
    whole = recorded_run.read_recording(GOLDEN)
    recording = whole._replace(samples=_decimated(whole.samples, every))
    analysis = measurement.analyse(recording)
    for row in analysis.rows:
        _covered(row)
    if every == 1:
        assert not _warned(analysis)
    else:  # 10 or 2.5 samples per revolution: the 0.4 % and 11-22 % errors are said
        warned = _warned(analysis)
        for name in ('time_ratio', 'peak_speed_ratio'):
            assert report.FIGURE_WORDS[name] + ' is not supported' in warned


def test_bounds_grow_at_least_as_the_cube_of_the_sample_interval():
    rows = [measurement.analyse(recorded_run.Recording('run', PAPER, _decimated(
        samples_for([-0.008], hold=8.0, rate=100.0), every), None)).rows[0]
        for every in (1, 2)]
    ratio = rows[1]['peak_cutting_speed_sampling_bound'] / rows[0][
        'peak_cutting_speed_sampling_bound']
    assert ratio >= 8.0 * (1 - 1e-9)  # h^3, times the motion's largest derivative near h
    assert np.isfinite(ratio) and math.isfinite(rows[0]['time_ratio_sampling_bound'])


def test_a_motor_runs_varying_speed_gets_no_kinematic_bound():
    """
    The kinematic bounds are derived at a constant input speed; the small shaper's motor at
    15 mm swings 30 % in speed within a revolution: its segment gets none.
    """
    from qrm_ros.analysis.recorded_drive import Drive
    from qrm_ros.core.dynamics import chain as dyn
    from qrm_ros.core.motor.motor_stepper import simulate
    offset = 0.015
    drive = Drive(dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper(),
                  dyn.MotorDrive.small_shaper())
    run = simulate(PAPER, drive.mass, drive.loads, drive.motor, offset, 2 * math.pi, 6.0,
                   100.0)
    steady = run.time > 3.0
    speed = run.input_speed[steady]
    assert (speed.max() - speed.min()) / speed.mean() > 0.25
    motion = kin.state(PAPER, offset, run.input_angle[steady], speed)
    time = run.time[steady]
    samples = recorded_run.Samples(
        time, run.input_angle[steady], speed, np.asarray(motion.flywheel_angle),
        np.asarray(motion.flywheel_speed), np.asarray(motion.ram_position),
        np.asarray(motion.ram_velocity), np.full(time.shape, offset), np.zeros(time.shape),
        run.efforts.input_torque[steady], run.efforts.offset_force[steady])
    analysis = measurement.analyse(recorded_run.Recording('run', PAPER, samples, None,
                                                          drive=drive))
    rows = [row for row in analysis.rows if row['stroke_pairs']]
    assert rows
    for row in rows:
        assert all(row[f'{name}_sampling_bound'] is None for name in BOUNDED_FIGURES)
    assert all(row['sampling_bound_problem'] == measurement.VARYING_SPEED for row in rows)
    assert measurement.VARYING_SPEED in _warned(analysis)
