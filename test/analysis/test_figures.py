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
"""The figures of an analysed run: theory curves are the core's, measured points the run's."""

import math
import os

import numpy as np

from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import figures
from qrm_ros.core import kinematics as kin
from synthetic_run import samples_for

PAPER = kin.Geometry.paper()


def test_figures_are_written_and_theory_curves_are_the_core(schedule_analysis, tmp_path):
    paths = figures.write_figures(schedule_analysis, str(tmp_path))
    assert sorted(os.path.basename(p) for p in paths) == sorted(figures.FIGURES)
    for path in paths:
        with open(path, 'rb') as handle:
            assert handle.read(8) == b'\x89PNG\r\n\x1a\n'
        assert os.path.getsize(path) > 20_000

    def theory_lines(figure):
        return [line for axes in figure.axes for line in axes.get_lines()
                if line.get_gid() == figures.THEORY]

    h = PAPER.pivot_distance
    tr_lines = theory_lines(figures.time_ratio_figure(schedule_analysis))
    x, y = tr_lines[0].get_data()
    checked = [kin.time_ratio_rk4(PAPER, d) for d in x[::50] * h]  # the paper's method
    np.testing.assert_allclose(y[::50], checked, rtol=1e-9)
    family = [line for axes in figures.time_ratio_figure(schedule_analysis).axes
              for line in axes.get_lines() if line.get_gid() == figures.THEORY_FAMILY]
    assert len(family) == len(figures.OTHER_CRANK_RADII)
    for line, crank_radius in zip(family, figures.OTHER_CRANK_RADII):
        other = kin.Geometry(PAPER.coupling_radius, crank_radius, PAPER.pivot_distance)
        x, y = line.get_data()
        checked = [kin.time_ratio_rk4(other, d) for d in x[::80] * h]
        np.testing.assert_allclose(y[::80], checked, rtol=1e-9)
    mid, peak = theory_lines(figures.speed_ratio_figure(schedule_analysis))
    x, y = mid.get_data()
    r1, r = PAPER.coupling_radius, PAPER.crank_radius
    np.testing.assert_allclose(y, (h + r) * (r1 + x * h) / ((h - r) * (r1 - x * h)), rtol=1e-12)
    x, y = peak.get_data()
    np.testing.assert_allclose(y, kin.peak_speed_ratio(PAPER, x * h), rtol=1e-12)
    for line, row in zip(theory_lines(figures.flywheel_speed_figure(schedule_analysis)),
                         schedule_analysis.rows):
        theta, omega2 = line.get_data()
        theta = np.radians(theta)
        d = row['offset']
        eq4 = 2 * math.pi * r1 * (r1 + d * np.sin(theta)) / (r1 ** 2 + d ** 2
                                                             + 2 * r1 * d * np.sin(theta))
        np.testing.assert_allclose(omega2, eq4, rtol=1e-12)
    lines = theory_lines(figures.ram_motion_figure(schedule_analysis))
    assert len(lines) == 2 * len(schedule_analysis.rows)


def test_figures_of_a_setting_outside_the_closed_form_show_the_measurement_only(tmp_path):
    narrow = kin.Geometry(0.005, PAPER.crank_radius, PAPER.pivot_distance)  # |δ| >= r1 below
    result = measurement.analyse(recorded_run.Recording('odd', narrow, samples_for([0.01]), None))
    (row,) = result.rows
    assert row['time_ratio_theory'] is None and row['time_ratio_measured'] is not None
    assert len(figures.write_figures(result, str(tmp_path))) == len(figures.FIGURES)
