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
Benchmark: closed-form TR and SR over a design grid against the paper's per-point RK4.

Prints configurations per second for the closed form (TR + SR together, and peak SR on its
own) and for RK4 integration of eq. (20) on a random sample of the same grid, their ratio,
and the largest relative disagreement between the two time ratios. Timings are medians of
several repeats measured in this run.

    python3 dev.py run python bench/bench_kinematics.py [--grid 1000] [--rk4-points 12]
"""

import argparse
import statistics
import time

import numpy as np

from qrm_ros import kinematics as kin


def median_seconds(function, repeats):
    timings = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        timings.append(time.perf_counter() - start)
    return statistics.median(timings)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--grid', type=int, default=1000, help='points per grid axis')
    parser.add_argument('--rk4-points', type=int, default=12)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()

    coupling_radius, pivot_distance = 0.025, 0.113
    offsets = np.linspace(-kin.SAFE_OFFSET_FRACTION, kin.SAFE_OFFSET_FRACTION,
                          args.grid) * coupling_radius
    radii = np.linspace(0.01, 0.1, args.grid)
    geometry = kin.Geometry(coupling_radius, radii[:, None], pivot_distance)
    configurations = args.grid * args.grid

    def closed_form():
        return kin.time_ratio(geometry, offsets[None, :]), kin.speed_ratio(geometry,
                                                                           offsets[None, :])

    closed_seconds = median_seconds(closed_form, args.repeats)
    time_ratios, _ = closed_form()

    rows = max(1, args.grid // 10)
    peak_geometry = kin.Geometry(coupling_radius, radii[:rows, None], pivot_distance)
    peak_seconds = median_seconds(
        lambda: kin.peak_speed_ratio(peak_geometry, offsets[None, :]), max(1, args.repeats // 2))
    peak_rate = rows * args.grid / peak_seconds

    rng = np.random.default_rng(20261121)
    sample = rng.integers(0, args.grid, size=(args.rk4_points, 2))
    start = time.perf_counter()
    rk4 = [kin.time_ratio_rk4(kin.Geometry(coupling_radius, radii[i], pivot_distance),
                              offsets[j]) for i, j in sample]
    rk4_seconds = time.perf_counter() - start
    disagreement = max(abs(value / time_ratios[i, j] - 1.0)
                       for value, (i, j) in zip(rk4, sample))

    closed_rate = configurations / closed_seconds
    rk4_rate = args.rk4_points / rk4_seconds
    print(f'closed-form TR+SR: {configurations} configurations in {closed_seconds:.3f} s '
          f'= {closed_rate:.3g} configurations/s (median of {args.repeats})')
    print(f'closed-form peak SR: {rows * args.grid} configurations in {peak_seconds:.3f} s '
          f'= {peak_rate:.3g} configurations/s')
    print(f'RK4 eq. (20) TR: {args.rk4_points} configurations in {rk4_seconds:.3f} s '
          f'= {rk4_rate:.3g} configurations/s')
    print(f'ratio closed-form TR+SR / RK4: {closed_rate / rk4_rate:.3g}x')
    print(f'largest relative TR disagreement closed form vs RK4: {disagreement:.2e}')


if __name__ == '__main__':
    main()
