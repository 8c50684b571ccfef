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
The effort figures' sampling bounds on runs of the real node (qrm_simulate), decimated.

A speed-drive run with the small shaper's loads at 1 kHz (60 rpm: 1000 samples per input
revolution) is decimated to 100, 10 and 2.5 samples per revolution; every stated bound
covers the figure's true error (measured against the ideal speed drive's exact theory,
speed_drive.pair_efforts), every figure without a bound or with one above 1e-3 of it is
warned about, and qrm_analyze exits 3 exactly then. A motor-drive run has efforts but no
bound for them (its steady running is simulated, not in closed form): exit 3, said.
"""

import json
import subprocess

import numpy as np
import pytest

from qrm_ros.analysis import measurement
from qrm_ros.analysis.measurement import VARYING_SPEED
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import report
from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.effort_sampling_bounds import EFFORT_BOUNDED_FIGURES
from qrm_ros.core.measurement.sampling_bounds import SUPPORTED_RELATIVE_ERROR
from qrm_ros.core.dynamics.speed_drive import pair_efforts
from ros_probe import installed_executable
from synthetic_run import write_run

PAPER = kin.Geometry.paper()
LOADS = dyn.Loads.small_shaper()
MASS = dyn.MassProperties.small_shaper()
OFFSET = 0.012
OFFSET_LARGE = 0.015
THEORY_TOLERANCE = 1e-9


def _simulate(*args):
    result = subprocess.run([installed_executable('qrm_simulate'), *map(str, args)],
                            capture_output=True, text=True, timeout=300)
    assert 'Traceback' not in result.stderr
    return result


def _loads():
    return [item for name, value in LOADS.as_dict().items()
            for item in ('-p', f'{name}:={value!r}')]


@pytest.fixture(scope='module')
def fine_run(tmp_path_factory):
    path = tmp_path_factory.mktemp('effort_sampling') / 'run.mcap'
    result = _simulate('--duration', 5, '-p', f'coupling_offset:={OFFSET!r}', '-p',
                       'publish_rate:=1000.0', *_loads(), '-o', path)
    assert result.returncode == exit_codes.EXIT_OK, result.stderr
    return recorded_run.read_recording(str(path))


def _decimated(samples, every):
    return recorded_run.Samples(*(None if field is None else field[::every]
                                  for field in samples))


@pytest.mark.parametrize('every', [1, 10, 100, 400])
def test_effort_bounds_cover_the_true_error_of_a_decimated_real_run(fine_run, every):
    analysis = measurement.analyse(fine_run._replace(
        samples=_decimated(fine_run.samples, every)))
    (row,) = [row for row in analysis.rows if row['stroke_pairs'] >= 1]
    assert row['offset'] == pytest.approx(OFFSET)
    exact = pair_efforts(PAPER, fine_run.drive.mass, LOADS, row['offset'],
                         row['input_speed'])._asdict()
    exact['speed_fluctuation'] = 0.0
    warned = '\n'.join(report.unsupported_by_sampling(analysis))
    unsupported = []
    for name in EFFORT_BOUNDED_FIGURES:
        measured, bound = row[f'{name}_measured'], row[f'{name}_sampling_bound']
        assert row[f'{name}_theory'] == pytest.approx(exact[name], rel=1e-12, abs=1e-12)
        if bound is not None:
            assert abs(measured - exact[name]) <= bound + THEORY_TOLERANCE * abs(
                exact[name]), (name, every, measured, exact[name], bound)
        relative = report.sampling_relative_bound(row, name)
        if relative is None or relative > SUPPORTED_RELATIVE_ERROR:
            unsupported.append(name)
            assert report.FIGURE_WORDS[name] + ' is not supported' in warned, name
    if every == 1:  # 1000 samples per revolution: every figure supported, nothing said
        assert not unsupported and not warned
    else:  # 100 per revolution at 12 mm: the return stroke's pieces are too short
        assert {'peak_input_torque', 'energy_per_pair'} <= set(unsupported)


@pytest.mark.parametrize('rate, code', [(500.0, exit_codes.EXIT_OK),
                                        (100.0, exit_codes.EXIT_INCOMPLETE)])
def test_exit_status_follows_the_effort_bounds(tmp_path, capsys, rate, code):
    path = tmp_path / 'run.mcap'
    result = _simulate('--duration', 4, '-p', f'coupling_offset:={OFFSET!r}', '-p',
                       f'publish_rate:={rate!r}', *_loads(), '-o', path)
    assert result.returncode == exit_codes.EXIT_OK, result.stderr
    found = qrm_analyze.main([str(path), '--json', str(tmp_path / 'r.json'), '--csv',
                              str(tmp_path / 'r.csv')])
    out, err = capsys.readouterr()
    assert found == code, err
    lines = out.splitlines()
    effort_header = next(line for line in lines if 'stroke pairs with efforts' in line)
    assert effort_header.endswith('error sampling')
    header = (tmp_path / 'r.csv').read_text().splitlines()[0].split(',')
    segments = json.loads((tmp_path / 'r.json').read_text())['segments']
    for name in EFFORT_BOUNDED_FIGURES:
        assert f'{name}_sampling_bound' in header
        assert all(f'{name}_sampling_bound' in segment for segment in segments)
    if code == exit_codes.EXIT_OK:
        assert 'sampling' not in err
    else:
        assert 'the peak input torque is not supported to 0.001 by the sampling' in err


def test_a_motor_run_has_no_effort_bound_and_exits_3(tmp_path, capsys):
    path = tmp_path / 'motor.mcap'
    result = _simulate('--duration', 6, '-p', 'drive:=motor', '-p',
                       f'coupling_offset:={OFFSET!r}', '-p', 'publish_rate:=500.0',
                       *_loads(), '-o', path)
    assert result.returncode == exit_codes.EXIT_OK, result.stderr
    found = qrm_analyze.main([str(path), '--json', str(tmp_path / 'r.json')])
    _, err = capsys.readouterr()
    assert found == exit_codes.EXIT_INCOMPLETE, err
    segments = [segment for segment in json.loads((tmp_path / 'r.json').read_text())[
        'segments'] if segment['stroke_pairs_with_efforts']]
    assert segments
    for segment in segments:
        assert np.isfinite(segment['peak_input_torque_measured'])
        for name in EFFORT_BOUNDED_FIGURES:
            assert segment[f'{name}_sampling_bound'] is None
    # Its speed varies: the kinematic bounds (taken at a constant speed) do not hold either.
    # One line says so, and does not send the user to a higher rate, which would not help.
    assert segments[0]['time_ratio_sampling_bound'] is None
    assert all(segment['sampling_bound_problem'] == VARYING_SPEED for segment in segments)
    (warning,) = [line for line in err.splitlines() if 'warning' in line]
    assert 'is supported to 0.001 by the sampling: ' + VARYING_SPEED in warning
    assert 'publish_rate' not in warning


def _synthetic_recording(tmp_path, rate, offset=0.015, hold=4.6):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [offset], hold=hold, rate=rate, mass=MASS, loads=LOADS)
    return recorded_run.read_recording(str(path))


def _without(samples, indices):
    kept = np.setdiff1d(np.arange(samples.time.size), indices)
    return recorded_run.Samples(*(None if field is None else field[kept]
                                  for field in samples))


def test_a_pair_sampled_too_coarsely_at_its_peak_is_left_out_of_the_effort_figures(
        tmp_path):
    """250 Hz at 15 mm: one lost sample at one pair's torque peak; the others carry it."""
    whole = _synthetic_recording(tmp_path, 250.0)
    clean = measurement.analyse(whole).rows[0]
    assert clean['stroke_pairs_left_out_of_efforts'] == 0
    torque = np.abs(whole.samples.input_torque)
    middle = whole.samples.time.size // 2
    peak = middle + int(np.argmax(torque[middle:middle + 250]))  # the peak of one revolution
    analysis = measurement.analyse(whole._replace(samples=_without(whole.samples, [peak])))
    (row,) = analysis.rows
    assert row['stroke_pairs'] == clean['stroke_pairs']
    assert row['stroke_pairs_left_out_of_efforts'] == 1
    assert row['stroke_pairs_with_efforts'] == row['stroke_pairs']
    assert not report.unsupported_by_sampling(analysis)
    exact = pair_efforts(PAPER, MASS, LOADS, OFFSET_LARGE, row['input_speed'])
    for name in ('peak_input_torque', 'rms_input_torque', 'energy_per_pair',
                 'peak_offset_force'):
        assert abs(row[f'{name}_measured'] - getattr(exact, name)) <= row[
            f'{name}_sampling_bound'], name
        assert row[f'{name}_sampling_bound'] <= SUPPORTED_RELATIVE_ERROR * getattr(exact, name)
    assert '(1 of them left out of these figures' in report.format_table(analysis)


def test_when_no_pair_is_supported_all_stay_in_and_it_is_said(tmp_path):
    """100 Hz at 15 mm: no pair's efforts are supported; none is left out, exit 3's warning."""
    analysis = measurement.analyse(_synthetic_recording(tmp_path, 100.0))
    (row,) = analysis.rows
    assert row['stroke_pairs_left_out_of_efforts'] == 0
    warned = '\n'.join(report.unsupported_by_sampling(analysis))
    assert 'the peak input torque is not supported' in warned
