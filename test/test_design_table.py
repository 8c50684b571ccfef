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
import math
import re

import pytest

from qrm_ros import design_table
from qrm_ros import kinematics as kin

R1, R, H_PIVOT = 0.025, 0.0505, 0.113


@pytest.fixture(scope='module')
def printed():
    buffer = io.StringIO()
    with redirect_stdout(buffer):
        assert design_table.main([]) == 0
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
    assert design_table.main(['--crank-radius', '0.2']) == 2
    assert 'crank_radius' in capsys.readouterr().err
    assert design_table.main(['--offsets-mm', '30']) == 2
    assert 'offset 0.03 m is out of range' in capsys.readouterr().err


def test_usage_errors_exit_2_naming_the_argument(capsys):
    # One exit-code policy for every command: 2 for usage or configuration errors.
    with pytest.raises(SystemExit) as stopped:
        design_table.main(['--input-speed', 'fast'])
    assert stopped.value.code == 2
    assert '--input-speed' in capsys.readouterr().err
