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
Benchmark: closed-form TR and SR, and exact peak speeds, over an (offset, crank radius) grid.

Prints configurations per second, as medians over repeats with the spread (lowest-highest),
for: closed-form TR + SR together; peak cutting and return speeds with peak SR (sampled
brackets and safeguarded Newton, `peak_ram_speeds`); the previous peak method (bracketing
with scipy's Chandrupatla root finder on a 48-sample grid, `_peak_speeds_bracketing`), on
slices of the same grid; and the paper's per-point RK4 of eq. (20) for TR. The methods
are timed in turn within each repeat, so each ratio is taken within a repeat (the machine
is shared and noisy) and its median and spread printed. Also the largest relative
disagreement of the TRs (closed form vs RK4) and of the peaks (new vs previous method).

    python3 dev.py run python bench/bench_kinematics.py [--grid 1000] [--repeats 5]

Where the time goes (cProfile). Before, 10^4 configurations: 83 % in state() and
input_angle_for_flywheel_angle() on the 2 x 47 samples per configuration (general code:
arctan2, both stages, accelerations), 14 % in Chandrupatla's iterations (each another round
of both). After, 9 x 10^4 configurations: 51 % in the sign test at the 24 + 12 samples
(and two crossings) per stroke pair (sin, cos, one square root, no division: a first
version sampling the velocity and its slope spent 62 % there and ran at 0.6x of today),
24 % bracket bookkeeping (column_stack, sort, nonzero, copies), 16 % the safeguarded
Newton iterations (run only on bracketed peaks, about 1.5 per stroke), the rest set-up.
The samples are the floor: fewer lose close peaks (see kinematics._PEAK_SAMPLES), and
even at no cost for the rest 40 samples of sin, cos and a square root per configuration
keep numpy below 10^6 configurations/s on this machine.
"""

import argparse
import statistics
import time

import numpy as np

from qrm_ros import kinematics as kin


def spread(values, unit=''):
    ordered = sorted(values)
    return (f'{statistics.median(ordered):.3g}{unit} ({ordered[0]:.3g}-{ordered[-1]:.3g}, '
            f'median of {len(ordered)})')


def timed(function):
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--grid', type=int, default=1000, help='points per grid axis')
    parser.add_argument('--peak-rows', type=int, default=50,
                        help='crank radii (grid rows) for the peak speeds')
    parser.add_argument('--bracketing-rows', type=int, default=5,
                        help='crank radii (grid rows) for the previous peak method')
    parser.add_argument('--rk4-points', type=int, default=12)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()

    coupling_radius, pivot_distance = 0.025, 0.113
    offsets = np.linspace(-kin.SAFE_OFFSET_FRACTION, kin.SAFE_OFFSET_FRACTION,
                          args.grid) * coupling_radius
    radii = np.linspace(0.01, 0.1, args.grid)
    geometry = kin.Geometry(coupling_radius, radii[:, None], pivot_distance)
    # Rows spread over the whole range of crank radii, not its first slice.
    peak_geometry = kin.Geometry(
        coupling_radius, radii[np.linspace(0, args.grid - 1, args.peak_rows).astype(int), None],
        pivot_distance)
    old_rows = np.linspace(0, args.grid - 1, args.bracketing_rows).astype(int)
    old_geometry = kin.Geometry(coupling_radius, radii[old_rows, None], pivot_distance)
    counts = {'closed': args.grid ** 2, 'peaks': args.peak_rows * args.grid,
              'bracketing': args.bracketing_rows * args.grid}

    def closed_form():
        return kin.time_ratio(geometry, offsets[None, :]), kin.speed_ratio(geometry,
                                                                           offsets[None, :])

    def peaks():
        cutting, returning = kin.peak_ram_speeds(peak_geometry, offsets[None, :])
        return cutting, returning, returning / cutting

    def bracketing():
        cutting, returning = kin._peak_speeds_bracketing(old_geometry, offsets[None, :])
        return cutting, returning, returning / cutting

    methods = {'closed': closed_form, 'peaks': peaks, 'bracketing': bracketing}
    rates = {name: [] for name in methods}
    for _ in range(args.repeats):
        for name, function in methods.items():
            rates[name].append(counts[name] / timed(function))

    time_ratios, _ = closed_form()
    new = kin.peak_ram_speeds(old_geometry, offsets[None, :])
    old = kin._peak_speeds_bracketing(old_geometry, offsets[None, :])
    peak_disagreement = max(float(np.max(np.abs(a / b - 1.0))) for a, b in zip(new, old))

    rng = np.random.default_rng(20261121)
    sample = rng.integers(0, args.grid, size=(args.rk4_points, 2))
    start = time.perf_counter()
    rk4 = [kin.time_ratio_rk4(kin.Geometry(coupling_radius, radii[i], pivot_distance),
                              offsets[j]) for i, j in sample]
    rk4_rate = args.rk4_points / (time.perf_counter() - start)
    disagreement = max(abs(value / time_ratios[i, j] - 1.0)
                       for value, (i, j) in zip(rk4, sample))

    def ratio(numerator, denominator):
        return spread([a / b for a, b in zip(rates[numerator], rates[denominator])], 'x')

    print(f'closed-form TR+SR ({counts["closed"]} configurations): '
          f'{spread(rates["closed"], "/s")}')
    print(f'peak speeds and peak SR ({counts["peaks"]} configurations): '
          f'{spread(rates["peaks"], "/s")}')
    print(f'previous peak method ({counts["bracketing"]} configurations): '
          f'{spread(rates["bracketing"], "/s")}')
    print(f'ratio peak speeds / previous peak method: {ratio("peaks", "bracketing")}')
    print(f'ratio peak speeds / closed-form TR+SR: {ratio("peaks", "closed")}')
    print(f'largest relative peak disagreement new vs previous: {peak_disagreement:.2e}')
    print(f'RK4 eq. (20) TR: {args.rk4_points} configurations, {rk4_rate:.3g}/s; ratio '
          f'closed-form TR+SR / RK4: {statistics.median(rates["closed"]) / rk4_rate:.3g}x')
    print(f'largest relative TR disagreement closed form vs RK4: {disagreement:.2e}')


if __name__ == '__main__':
    main()
