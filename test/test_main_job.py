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
"""The main job end to end, with a short schedule: real processes, real DDS, real files."""

import json
import math
import os

import pytest

from qrm_ros import kinematics as kin
from qrm_ros import main_job


def test_main_job_runs_a_short_schedule_end_to_end(tmp_path, capsys):
    speed = 4 * math.pi  # two stroke pairs a second keeps the test short
    code = main_job.main(['--offsets-mm', '-6', '8', '--pairs', '2', '--input-speed',
                          repr(speed), '--output-dir', str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    (folder,) = [p for p in tmp_path.iterdir() if p.name.startswith('qrm_')]
    for name in ('run.mcap', 'results.json', 'results.csv', 'shaper_sim.log',
                 'mcap_recorder.log'):
        assert (folder / name).is_file(), name
    assert sorted(os.listdir(folder / 'figures')) == sorted(
        ['fig10_time_ratio.png', 'fig11_speed_ratio.png', 'fig12_flywheel_speed.png',
         'ram_motion.png'])
    assert str(folder / 'run.mcap') in out
    document = json.loads((folder / 'results.json').read_text())
    segments = document['segments']
    assert [s['offset'] for s in segments] == [-0.006, 0.008]  # exactly what was commanded
    geometry = kin.Geometry.paper()
    tolerance = (speed * 0.01) ** 3  # the stroke finder's bound at 100 Hz
    for segment in segments:
        assert segment['stroke_pairs'] >= 2
        assert segment['input_speed'] == pytest.approx(speed, rel=1e-15)
        assert segment['time_ratio_measured'] == pytest.approx(
            kin.time_ratio_rk4(geometry, segment['offset']), rel=tolerance)
        eq25 = kin.speed_ratio_eq25(geometry, segment['offset'])
        assert segment['speed_ratio_measured'] == pytest.approx(eq25, rel=tolerance)


def test_main_job_refuses_bad_options(tmp_path, capsys):
    assert main_job.main(['--pairs', '0', '--output-dir', str(tmp_path)]) == 1
    assert '--pairs must be at least 1' in capsys.readouterr().err
    assert main_job.main(['--input-speed', 'nan', '--output-dir', str(tmp_path)]) == 1
    assert '--input-speed must be finite and non-zero' in capsys.readouterr().err
    assert main_job.main(['--offsets-mm', '0', '23', '--output-dir', str(tmp_path)]) == 1
    assert ('--offsets-mm: 23 mm is outside what shaper_sim accepts, |offset| <= 22.5 mm'
            in capsys.readouterr().err)
    assert not list(tmp_path.iterdir())  # nothing started, nothing written
