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
Tests of the design table: every printed figure against an independent derivation.

The printed TR is checked against RK4 of the paper's eq. (20), SR against eq. (25), the SR = 1
offset against eq. (26), the stroke times against the period and the stroke against its
closed form.
"""

from contextlib import redirect_stdout
import io
import json
import math
import re

import numpy as np
import pytest

from qrm_ros.analysis import design_table
from qrm_ros.cli import qrm_design
from qrm_ros.core import kinematics as kin

R1, R, H_PIVOT = 0.025, 0.0505, 0.113


@pytest.fixture(scope='module')
def printed():
    buffer = io.StringIO()
    with redirect_stdout(buffer):
        assert qrm_design.main([]) == 0
    return buffer.getvalue()


def table_rows(text):
    rows = []
    for line in text.splitlines():
        fields = line.split()
        if len(fields) == 9 and re.fullmatch(r'-?\d+\.\d\d', fields[0]):
            rows.append([float(f) for f in fields])
    return rows


def test_table_covers_the_default_offsets(printed):
    rows = table_rows(printed)
    assert [row[0] for row in rows] == pytest.approx(list(design_table.DEFAULT_OFFSETS_MM))


def test_printed_ratios_match_independent_derivations(printed):
    for offset_mm, over_h, tr, sr, peak_sr, t_cut, t_ret, v_cut, v_ret in table_rows(printed):
        offset = offset_mm / 1e3
        assert over_h == pytest.approx(offset / H_PIVOT, abs=6e-6)
        assert tr == pytest.approx(kin.time_ratio_rk4(kin.Geometry.paper(), offset), abs=6e-6)
        eq25 = (H_PIVOT + R) * (R1 + offset) / ((H_PIVOT - R) * (R1 - offset))
        assert sr == pytest.approx(eq25, abs=6e-6)
        assert peak_sr == pytest.approx(v_ret / v_cut, rel=1e-4)
        assert t_cut + t_ret == pytest.approx(1.0, abs=1e-4)  # one revolution at 60 rpm
        assert t_cut / t_ret == pytest.approx(tr, rel=2e-3)
        assert peak_sr <= sr + 6e-6 or offset < 0  # peaks can only beat mid-stroke speeds


def test_printed_unity_speed_ratio_offset_is_eq26(printed):
    match = re.search(r'SR = 1 .* at offset (-?\d+\.\d+) mm', printed)
    assert float(match.group(1)) == pytest.approx(-R * R1 / H_PIVOT * 1e3, abs=1e-6)


def test_printed_time_ratio_offsets_round_trip(printed):
    for target, offset_mm in re.findall(r'TR = (\d) at offset (-?\d+\.\d+) mm', printed):
        offset = float(offset_mm) / 1e3
        assert kin.time_ratio_rk4(kin.Geometry.paper(), offset) == pytest.approx(
            float(target), abs=1e-5)


def test_printed_stroke_is_the_closed_form(printed):
    stroke = float(re.search(r'ram stroke = (\d+\.\d+) mm', printed).group(1))
    assert stroke == pytest.approx(2 * 200 * R / math.sqrt(H_PIVOT ** 2 - R ** 2), abs=1e-4)


def test_bad_geometry_exits_with_a_message(capsys):
    assert qrm_design.main(['--crank-radius', '0.2']) == 2
    assert 'crank_radius' in capsys.readouterr().err
    assert qrm_design.main(['--offsets-mm', '30']) == 2
    assert 'offset 0.03 m is out of range' in capsys.readouterr().err


def test_usage_errors_exit_2_naming_the_argument(capsys):
    # One exit-code policy for every command: 2 for usage or configuration errors.
    with pytest.raises(SystemExit) as stopped:
        qrm_design.main(['--input-speed', 'fast'])
    assert stopped.value.code == 2
    assert '--input-speed' in capsys.readouterr().err


def run_design(argv, capsys):
    code = qrm_design.main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


GEARBOX_ARGS = ['gearbox', '--min-cutting-speed', '0.1', '--max-cutting-speed', '0.5']


def test_gearbox_json_holds_the_plan_in_si_units(capsys):
    code, out, _ = run_design(GEARBOX_ARGS + ['--json'], capsys)
    assert code == 0
    data = json.loads(out)
    geometry = kin.Geometry(**data['geometry'])
    assert data['min_cutting_speed'] == 0.1 and data['max_cutting_speed'] == 0.5
    assert data['definition'] == 'mean' and data['min_time_ratio'] == 1.0
    assert data['max_offset'] == geometry.max_safe_offset
    steps = data['steps']
    assert [step['input_speed'] for step in steps] == sorted(s['input_speed'] for s in steps)
    assert steps[0]['cutting_speed_min'] == 0.1 and steps[-1]['cutting_speed_max'] == 0.5
    for lower, upper in zip(steps, steps[1:]):
        assert lower['cutting_speed_max'] == upper['cutting_speed_min']
    for step in steps:
        at_ends = kin.mean_cutting_speed(geometry, [step['offset_at_min'], step['offset_at_max']],
                                         step['input_speed'])
        assert list(at_ends) == pytest.approx(
            [step['cutting_speed_min'], step['cutting_speed_max']], rel=1e-11)
    assert data['band_ratio'] == pytest.approx(
        data['offsets']['fastest_per_input_speed'] / data['offsets']['slowest_per_input_speed'])
    conventional = {box['progression_ratio']: box for box in data['conventional']}
    assert sorted(conventional) == [1.12, 1.26, 1.41, 1.58, 2.0]
    for ratio, box in conventional.items():
        assert box['step_count'] == len(box['input_speeds']) == len(box['cutting_speeds'])
        assert ratio ** box['step_count'] >= 5.0 > ratio ** (box['step_count'] - 1)
        assert box['max_shortfall'] == pytest.approx(1 - 1 / ratio)
        assert list(kin.mean_cutting_speed(geometry, 0.0, np.array(box['input_speeds']))) == \
            pytest.approx(box['cutting_speeds'], rel=1e-12)


def test_gearbox_table_prints_the_json_numbers(capsys):
    _, out, _ = run_design(GEARBOX_ARGS + ['--definition', 'peak', '--json'], capsys)
    data = json.loads(out)
    code, text, _ = run_design(GEARBOX_ARGS + ['--definition', 'peak'], capsys)
    assert code == 0
    rows = [line.split() for line in text.splitlines()
            if re.fullmatch(r'\s+\d+ +\d+\.\d{5} .*', line)]
    assert len(rows) == len(data['steps'])
    for row, step in zip(rows, data['steps']):
        number, speed, rpm, v_min, v_max, d_min, d_max = (float(f) for f in row)
        assert speed == pytest.approx(step['input_speed'], abs=6e-6)
        assert rpm == pytest.approx(step['input_speed'] * 30 / math.pi, abs=6e-4)
        assert v_min == pytest.approx(step['cutting_speed_min'], abs=6e-7)
        assert v_max == pytest.approx(step['cutting_speed_max'], abs=6e-7)
        assert d_min == pytest.approx(step['offset_at_min'] * 1e3, abs=6e-7)
        assert d_max == pytest.approx(step['offset_at_max'] * 1e3, abs=6e-7)
    counts = dict(re.findall(r'^\s+(\d+(?:\.\d+)?)\s+\d+\.\d %\s+(\d+)$', text, re.M))
    assert {float(k): int(v) for k, v in counts.items()} == {
        box['progression_ratio']: box['step_count'] for box in data['conventional']}
    assert f'with the offset: {len(data["steps"])} steps' in text


def test_gearbox_takes_geometry_and_limits(capsys):
    code, out, _ = run_design(GEARBOX_ARGS + ['--json', '--crank-radius', '0.04',
                                              '--max-offset', '0.01', '--min-time-ratio', '1.3'],
                              capsys)
    assert code == 0
    data = json.loads(out)
    assert data['geometry']['crank_radius'] == 0.04
    assert data['max_offset'] == 0.01 and data['min_time_ratio'] == 1.3
    geometry = kin.Geometry(**data['geometry'])
    for step in data['steps']:
        offsets = np.array([step['offset_at_min'], step['offset_at_max']])
        assert np.all(np.abs(offsets) <= 0.01)
        assert np.all(kin.time_ratio(geometry, offsets) >= 1.3 * (1 - 1e-12))


@pytest.mark.parametrize('extra, words', [
    (['--min-cutting-speed', '0.6'], 'min_cutting_speed (0.6 m/s) must be below'),
    (['--min-cutting-speed', '-1'], 'min_cutting_speed must be one number > 0 m/s'),
    (['--max-offset', '0'], 'leave one mean cutting speed per step'),
    (['--min-time-ratio', '30'], 'min_time_ratio 30 is out of reach'),
    (['--crank-radius', '0.2'], 'crank_radius'),
])
def test_gearbox_bad_requests_exit_2_with_reasons(capsys, extra, words):
    code, out, err = run_design(GEARBOX_ARGS + extra, capsys)
    assert code == 2 and out == ''
    assert err.startswith('qrm_design gearbox: ') and words in err


def test_gearbox_figure_that_cannot_be_written_exits_1_naming_it(capsys):
    # A write error is a failure while running (1), not bad input (2).
    code, out, err = run_design(GEARBOX_ARGS + ['--figure', '/nonexistent-folder/ladder.png'],
                                capsys)
    assert code == 1 and out == ''
    assert err == ('qrm_design gearbox: cannot write /nonexistent-folder/ladder.png: No such '
                   'file or directory\n')


def test_gearbox_usage_errors_exit_2(capsys):
    for argv in (['gearbox'], GEARBOX_ARGS + ['--definition', 'median'],
                 GEARBOX_ARGS + ['--progression-ratio', '1.3']):
        with pytest.raises(SystemExit) as stopped:
            qrm_design.main(argv)
        assert stopped.value.code == 2
    assert '--progression-ratio' in capsys.readouterr().err


def test_subcommands_are_listed_in_the_table_help(capsys):
    with pytest.raises(SystemExit):
        qrm_design.main(['--help'])
    assert 'qrm_design gearbox --help' in capsys.readouterr().out
    assert set(qrm_design.SUBCOMMANDS) >= {'gearbox'}


def test_gearbox_figure_draws_the_plan(tmp_path, capsys):
    path = tmp_path / 'ladder.png'
    code, out, _ = run_design(GEARBOX_ARGS + ['--json', '--figure', str(path)], capsys)
    assert code == 0
    assert path.stat().st_size > 20000
    assert [p.name for p in tmp_path.iterdir()] == ['ladder.png']  # no temporary left
    from qrm_ros.core.design import gearbox
    from qrm_ros.analysis import gearbox_figure
    from qrm_ros.analysis.plotting import plt
    data = json.loads(out)
    plan = gearbox.plan_gearbox(kin.Geometry.paper(), 0.1, 0.5)
    figure = gearbox_figure.speed_ladder_figure(plan, 1.41)
    try:
        rays, saw = figure.axes
        bands = [line for line in rays.lines if line.get_gid() == gearbox_figure.BAND]
        assert [(line.get_xdata()[0], *line.get_ydata()) for line in bands] == [
            (s['input_speed'], s['cutting_speed_min'], s['cutting_speed_max'])
            for s in data['steps']]
        shaded = [patch for patch in saw.patches if patch.get_gid() == gearbox_figure.BAND]
        spans = [(p.get_x(), p.get_x() + p.get_width()) for p in shaded]
        np.testing.assert_allclose(spans, [(s['cutting_speed_min'], s['cutting_speed_max'])
                                           for s in data['steps']], rtol=1e-12)
        box = next(b for b in data['conventional'] if b['progression_ratio'] == 1.41)
        points = next(line for line in rays.lines
                      if line.get_gid() == gearbox_figure.CONVENTIONAL)
        assert list(points.get_xdata()) == box['input_speeds']
        assert list(points.get_ydata()) == box['cutting_speeds']
        sawtooth = next(line for line in saw.lines if line.get_gid() == gearbox_figure.SAWTOOTH)
        wanted, obtained = sawtooth.get_xdata(), sawtooth.get_ydata() * sawtooth.get_xdata()
        # Each wanted speed is cut at the fastest conventional step not above it.
        for v, got in zip(wanted[::97], obtained[::97]):
            assert got == max(c for c in box['cutting_speeds'] if c <= v * (1 + 1e-12))
        assert np.min(sawtooth.get_ydata()) >= 1 - box['max_shortfall'] - 1e-12
    finally:
        plt.close(figure)
