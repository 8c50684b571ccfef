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
"""qrm_main --offline: the schedule as a scenario, and the whole job run through it."""

import argparse
from dataclasses import replace
import json
import math

import pytest

from qrm_ros.cli import qrm_main
from qrm_ros.cli.main_job_offline import offline_scenario, SETTLING_PAIRS
from qrm_ros.cli.main_job_plan import short_stroke_plan, STROKE_RATE_LIMIT
from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics.chain import Loads
from qrm_ros.node.offline.scenario import Event


def test_each_offset_is_held_for_its_travel_and_its_pairs():
    options = argparse.Namespace(
        offsets_mm=[-10.0, 0.0, 10.0], pairs=3, input_speed=9.0, offset_rate_limit=0.02,
        drive='motor', publish_rate=100.0, cutting_force=0.0, ram_friction=0.0,
        cutting_length=0.0, short_stroke_mm=0.0)
    scenario = offline_scenario(options)
    hold = (3 + SETTLING_PAIRS) * 2 * math.pi / 9.0
    travel = 0.010 / 0.02  # 10 mm at 20 mm/s
    assert scenario.events == (
        Event(pytest.approx(hold), 'set', {'coupling_offset': 0.0}),
        Event(pytest.approx(2 * hold + travel), 'set', {'coupling_offset': 0.01}))
    assert scenario.duration == pytest.approx(3 * hold + 2 * travel)
    assert scenario.parameters['coupling_offset'] == -0.01
    assert scenario.parameters['drive'] == 'motor'
    assert scenario.parameters['input_speed'] == 9.0


def test_the_short_stroke_follows_as_the_live_job_runs_it():
    options = argparse.Namespace(
        offsets_mm=[10.0], pairs=3, input_speed=9.0, offset_rate_limit=0.02, drive='speed',
        publish_rate=100.0, cutting_force=400.0, ram_friction=20.0, cutting_length=0.15,
        short_stroke_mm=60.0)
    scenario = offline_scenario(options)
    hold = (3 + SETTLING_PAIRS) * 2 * math.pi / 9.0
    plan = short_stroke_plan(60.0, 0.15)
    long_stroke = kin.Geometry.paper()
    screw = (long_stroke.ram_stroke - 0.06) / STROKE_RATE_LIMIT  # longer than the offset's
    assert screw > 0.010 / 0.02
    short = replace(long_stroke, crank_radius=0.06 * long_stroke.pivot_distance / math.sqrt(
        4 * long_stroke.ram_height ** 2 + 0.06 ** 2))
    held = kin.offset_for_time_ratio(short, plan.time_ratio)
    assert scenario.events == (
        Event(pytest.approx(hold), 'set', {'coupling_offset': 0.0, 'cutting_length': 0.048,
                                           'stroke_length': 0.06}),
        Event(pytest.approx(2 * hold + screw), 'set', {'time_ratio_target': plan.time_ratio}))
    assert scenario.duration == pytest.approx(3 * hold + screw + abs(held) / 0.02)
    assert scenario.parameters['stroke_rate_limit'] == STROKE_RATE_LIMIT


@pytest.mark.slow
def test_the_main_job_offline_measures_each_offset_and_the_short_stroke(tmp_path, capsys):
    code = qrm_main.main(['--offline', '--offsets-mm', '-10', '10', '--pairs', '2',
                          '--output-dir', str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert 'simulating' in out
    results = next(tmp_path.glob('qrm_*/results.json'))
    segments = json.loads(results.read_text())['segments']
    plan = short_stroke_plan(qrm_main.SHORT_STROKE_MM, Loads.small_shaper().cutting_length)
    offsets = [segment['offset'] for segment in segments]
    assert offsets[:3] == [pytest.approx(-0.01), pytest.approx(0.01), 0.0]
    assert [segment['stroke_length'] for segment in segments[2:]] == [
        pytest.approx(plan.stroke, rel=1e-12)] * 2
    for segment in segments:
        assert segment['stroke_pairs'] >= 2
        geometry = replace(kin.Geometry.paper(), crank_radius=segment['crank_radius'])
        assert segment['time_ratio_measured'] == pytest.approx(
            kin.time_ratio(geometry, segment['offset']), rel=1e-4)
    # The hold gives the short stroke the long stroke's time ratio at offset 0 (and the
    # effort theory has the shortened workpiece: the parameter events are read).
    assert segments[3]['time_ratio_measured'] == pytest.approx(plan.time_ratio, rel=1e-4)
    assert all(segment['peak_input_torque_theory'] is not None for segment in segments)


def test_offline_and_live_exclude_each_other(capsys):
    with pytest.raises(SystemExit) as exited:
        qrm_main.main(['--offline', '--live'])
    assert exited.value.code == 2
    assert '--offline and --live exclude each other' in capsys.readouterr().err
