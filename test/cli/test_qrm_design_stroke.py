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
``qrm_design stroke`` and ``--stroke-length``: every printed figure against an independent
derivation (the time ratio by RK4 of the paper's eq. (20), eq. (28) at offset 0, the
flywheel swing from eq. (4)'s extremes, the crank radius written out).
"""

from contextlib import redirect_stderr, redirect_stdout
import dataclasses
import io
import json
import math

import pytest

from qrm_ros.cli import qrm_design
from qrm_ros.core import kinematics as kin

R1, H_PIVOT, RAM_HEIGHT = 0.025, 0.113, 0.2


def run(argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        status = qrm_design.main(argv)
    return status, out.getvalue(), err.getvalue()


def test_stroke_table_against_rk4_and_the_closed_forms():
    status, out, _ = run(['stroke', '--time-ratio', '1.8', '--strokes-mm', '60', '120', '200',
                          '--json'])
    assert status == 0
    data = json.loads(out)
    for row, stroke in zip(data['rows'], (0.06, 0.12, 0.2)):
        radius = stroke * H_PIVOT / math.sqrt(4 * RAM_HEIGHT ** 2 + stroke ** 2)
        assert row['crank_radius'] == pytest.approx(radius, rel=1e-14)
        half = math.asin(radius / H_PIVOT)
        assert row['time_ratio_at_zero_offset'] == pytest.approx(
            (math.pi + 2 * half) / (math.pi - 2 * half), rel=1e-12)  # eq. (28)
        geometry = dataclasses.replace(kin.Geometry.paper(), crank_radius=radius)
        assert row['reachable']
        assert kin.time_ratio_rk4(geometry, row['offset'], 1 << 16) == pytest.approx(
            1.8, rel=1e-8)
        offset = abs(row['offset'])
        assert row['flywheel_speed_swing'] == pytest.approx((R1 + offset) / (R1 - offset),
                                                            rel=1e-14)
    # A short stroke loses its quick return; a positive offset gives it back.
    assert data['rows'][0]['time_ratio_at_zero_offset'] < 1.25 and data['rows'][0]['offset'] > 0


def test_stroke_table_text_and_an_unreachable_row():
    status, out, _ = run(['stroke', '--time-ratio', '12', '--strokes-mm', '60', '200'])
    assert status == 0
    lines = out.splitlines()
    assert lines[0].startswith('time ratio wanted: 12')
    assert '(out of reach: the nearest safe offset)' in lines[4]  # 60 mm: up to 8.68
    assert 'out of reach' not in lines[5]


@pytest.mark.parametrize('argv, message', [
    (['stroke', '--strokes-mm', '-5'], 'stroke length -0.005 m is out of range'),
    (['stroke', '--time-ratio', '0'], 'time ratio 0.0 is out of range'),
    (['stroke', '--strokes-mm', 'nan'], 'stroke length nan m is out of range'),
    (['--stroke-length', '0.1', '--crank-radius', '0.03'], 'not both'),
    (['--stroke-length', '-0.1'], '--stroke-length -0.1 m is out of range'),
])
def test_bad_stroke_input_is_refused_in_one_line(argv, message):
    status, out, err = run(argv)
    assert status == 2 and not out and message in err and len(err.strip().splitlines()) == 1


def test_stroke_length_sets_the_crank_radius_of_the_design_table():
    status, out, _ = run(['--stroke-length', '0.1', '--cutting-length', '0.08',
                          '--offsets-mm', '0', '--json'])
    assert status == 0
    row, = json.loads(out)['rows']
    radius = 0.1 * H_PIVOT / math.sqrt(4 * RAM_HEIGHT ** 2 + 0.01)
    half = math.asin(radius / H_PIVOT)
    assert row['time_ratio'] == pytest.approx((math.pi + 2 * half) / (math.pi - 2 * half),
                                              rel=1e-12)
