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
for: closed-form TR + SR together; peak cutting and return speeds with peak SR
(`peak_ram_speeds`: the compiled search, qrm_ros.core.kinematics.peak_kernel, on sweeps of at least
peak_speeds.COMPILED_MIN_CONFIGURATIONS), on grid rows and on random designs (offsets up to
0.999 r1, random crank phases: nothing for the search to reuse between configurations);
the previous method, the same search in numpy (`peak_speeds_numpy`), and the one before
(bracketing with scipy's Chandrupatla root finder on a 48-sample grid,
`peak_speeds_bracketing`), on slices of the same grid; and the paper's per-point RK4 of
eq. (20) for TR. The methods are timed in turn within each repeat, so each ratio is taken
within a repeat (the machine is shared and noisy) and its median and spread printed. Also
what the compiled search costs before its first answer (importing numba, then compiling or
loading the cached machine code), and the largest relative disagreements: TRs (closed form
vs RK4), peaks (compiled vs numpy search on the random designs, compiled vs bracketing).

    python3 dev.py run python bench/bench_kinematics.py [--grid 1000] [--repeats 5]

Where the time goes (cProfile for numpy; the compiled search timed in CPU time with its
Newton steps, or all but one sample per stroke, switched off). Bracketing, 10^4
configurations: 83 % in state() and input_angle_for_flywheel_angle() on the 2 x 47 samples
per configuration (general code: arctan2, both stages, accelerations), 14 % in
Chandrupatla's iterations (each another round of both). The numpy search, 9 x 10^4
configurations: 51 % in the sign test at the 24 + 12 samples (and two crossings) per
stroke pair (sin, cos, one square root, no division), 24 % bracket bookkeeping
(column_stack, sort, nonzero, copies), 16 % the safeguarded Newton iterations (run only on
bracketed peaks, 2.5 per configuration, 2.5 steps each), the rest set-up: about 4.4 us per
configuration, most of it numpy's passes over temporaries. The compiled search, 10^5
random designs: a first port of the same steps took 1.0 us per configuration (0.6 us
without its Newton steps), calling sin and cos (24 ns a pair here) about 12 times per
configuration and once per Newton step, and eight divisions per step. Now sin and cos are
called once per configuration (for its phase, and not even that where the phase repeats)
and once per stroke (its best root, taken again): the samples' come from rotating the
reversal's (sin = -r/h there, exact) by the sample spacing, the crossings' are +-those of
the phase, and Newton rotates its point by each step by a series; a step takes three
divisions; multiplies and adds may fuse (fastmath 'contract' only: 8 %). 0.64 us per random
design: Newton 0.28 (about 6 steps, latency-bound: a square root, three divisions and the
rotation in a chain), the 40 samples 0.16, set-up and the two final speeds 0.2; 0.5 us on
the grid rows (phase and lever geometry repeat there).
"""

import argparse
import statistics
import time

import numpy as np

from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics import peak_speeds
from qrm_ros.core.kinematics.peak_speeds_bracketing import peak_speeds_bracketing


def spread(values, unit=''):
    ordered = sorted(values)
    return (f'{statistics.median(ordered):.3g}{unit} ({ordered[0]:.3g}-{ordered[-1]:.3g}, '
            f'median of {len(ordered)})')


def timed(function):
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def random_designs(count, seed):
    """Designs over the whole space: every geometry field random, offsets up to 0.999 r1."""
    rng = np.random.default_rng(seed)
    pivot_distance = rng.uniform(0.05, 0.3, count)
    coupling_radius = rng.uniform(0.01, 0.05, count)
    geometry = kin.Geometry(coupling_radius, rng.uniform(0.03, 0.97, count) * pivot_distance,
                            pivot_distance, rng.uniform(0.05, 0.5, count),
                            rng.uniform(-np.pi, np.pi, count))
    return geometry, rng.uniform(-0.999, 0.999, count) * coupling_radius


def first_answer():
    """
    Seconds to import the compiled search and to its first answer, and how it got its code.

    Importing it compiles peak_kernel.peak_speeds for its signature, or loads the cache.
    """
    start = time.perf_counter()
    search = peak_speeds.compiled_peak_search()
    imported = time.perf_counter()
    if search is None:
        return None
    peak_speeds.peak_speeds_forward(kin.Geometry.paper(),
                                    np.zeros(peak_speeds.COMPILED_MIN_CONFIGURATIONS))
    answered = time.perf_counter()
    hits = sum(search.stats.cache_hits.values())
    return imported - start, answered - imported, 'from the cache' if hits else 'compiled'


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--grid', type=int, default=1000, help='points per grid axis')
    parser.add_argument('--peak-rows', type=int, default=50,
                        help='crank radii (grid rows) for the peak speeds')
    parser.add_argument('--random-designs', type=int, default=50_000,
                        help='random designs for the peak speeds')
    parser.add_argument('--numpy-rows', type=int, default=10,
                        help='crank radii (grid rows) for the previous (numpy) peak search')
    parser.add_argument('--bracketing-rows', type=int, default=5,
                        help='crank radii (grid rows) for the bracketing peak method')
    parser.add_argument('--rk4-points', type=int, default=12)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()

    startup = first_answer()
    coupling_radius, pivot_distance = 0.025, 0.113
    offsets = np.linspace(-kin.SAFE_OFFSET_FRACTION, kin.SAFE_OFFSET_FRACTION,
                          args.grid) * coupling_radius
    radii = np.linspace(0.01, 0.1, args.grid)
    geometry = kin.Geometry(coupling_radius, radii[:, None], pivot_distance)

    def rows(count):
        # Rows spread over the whole range of crank radii, not its first slice.
        chosen = radii[np.linspace(0, args.grid - 1, count).astype(int), None]
        return kin.Geometry(coupling_radius, chosen, pivot_distance)

    peak_geometry, numpy_geometry = rows(args.peak_rows), rows(args.numpy_rows)
    old_geometry = rows(args.bracketing_rows)
    random_geometry, random_offsets = random_designs(args.random_designs, 20261124)
    counts = {'closed': args.grid ** 2, 'peaks': args.peak_rows * args.grid,
              'random': args.random_designs, 'numpy': args.numpy_rows * args.grid,
              'bracketing': args.bracketing_rows * args.grid}

    def closed_form():
        return kin.time_ratio(geometry, offsets[None, :]), kin.speed_ratio(geometry,
                                                                           offsets[None, :])

    def with_ratio(cutting, returning):
        return cutting, returning, returning / cutting

    methods = {
        'closed': closed_form,
        'peaks': lambda: with_ratio(*kin.peak_ram_speeds(peak_geometry, offsets[None, :])),
        'random': lambda: with_ratio(*kin.peak_ram_speeds(random_geometry, random_offsets)),
        'numpy': lambda: with_ratio(*peak_speeds.peak_speeds_numpy(numpy_geometry,
                                                                   offsets[None, :])),
        'bracketing': lambda: with_ratio(*peak_speeds_bracketing(old_geometry,
                                                                 offsets[None, :])),
    }
    rates = {name: [] for name in methods}
    for _ in range(args.repeats):
        for name, function in methods.items():
            rates[name].append(counts[name] / timed(function))

    def disagreement(new, old):
        return max(float(np.max(np.abs(a / b - 1.0))) for a, b in zip(new, old))

    time_ratios, _ = closed_form()
    against_numpy = disagreement(kin.peak_ram_speeds(random_geometry, random_offsets),
                                 peak_speeds.peak_speeds_numpy(random_geometry, random_offsets))
    # The bracketing method's 48 samples miss peaks beyond the safe offset: grid rows only.
    grid_rows = rows(peak_speeds.COMPILED_MIN_CONFIGURATIONS // args.grid + 1)
    against_bracketing = disagreement(kin.peak_ram_speeds(grid_rows, offsets[None, :]),
                                      peak_speeds_bracketing(grid_rows, offsets[None, :]))

    rng = np.random.default_rng(20261121)
    sample = rng.integers(0, args.grid, size=(args.rk4_points, 2))
    start = time.perf_counter()
    rk4 = [kin.time_ratio_rk4(kin.Geometry(coupling_radius, radii[i], pivot_distance),
                              offsets[j]) for i, j in sample]
    rk4_rate = args.rk4_points / (time.perf_counter() - start)
    rk4_disagreement = max(abs(value / time_ratios[i, j] - 1.0)
                           for value, (i, j) in zip(rk4, sample))

    def ratio(numerator, denominator):
        return spread([a / b for a, b in zip(rates[numerator], rates[denominator])], 'x')

    if startup is None:
        print('compiled peak search: numba is not installed, the numpy search runs instead')
    else:
        print(f'compiled peak search before its first answer: import {startup[0]:.2f} s '
              f'(numba, and the machine code {startup[2]}), first call on '
              f'{peak_speeds.COMPILED_MIN_CONFIGURATIONS} configurations {startup[1]:.2f} s')
    print(f'closed-form TR+SR ({counts["closed"]} configurations): '
          f'{spread(rates["closed"], "/s")}')
    print(f'peak speeds and peak SR, grid rows ({counts["peaks"]} configurations): '
          f'{spread(rates["peaks"], "/s")}')
    print(f'peak speeds and peak SR, random designs ({counts["random"]} configurations): '
          f'{spread(rates["random"], "/s")}')
    print(f'previous peak search, numpy ({counts["numpy"]} configurations): '
          f'{spread(rates["numpy"], "/s")}')
    print(f'bracketing peak method ({counts["bracketing"]} configurations): '
          f'{spread(rates["bracketing"], "/s")}')
    print(f'ratio peak speeds (grid rows) / numpy search: {ratio("peaks", "numpy")}')
    print(f'ratio peak speeds (grid rows) / bracketing method: {ratio("peaks", "bracketing")}')
    print(f'ratio peak speeds / closed-form TR+SR: grid rows {ratio("peaks", "closed")}, '
          f'random designs {ratio("random", "closed")}')
    print(f'largest relative peak disagreement: compiled vs numpy search (random designs) '
          f'{against_numpy:.2e}, compiled vs bracketing (grid rows) {against_bracketing:.2e}')
    print(f'RK4 eq. (20) TR: {args.rk4_points} configurations, {rk4_rate:.3g}/s; ratio '
          f'closed-form TR+SR / RK4: {statistics.median(rates["closed"]) / rk4_rate:.3g}x')
    print(f'largest relative TR disagreement closed form vs RK4: {rk4_disagreement:.2e}')


if __name__ == '__main__':
    main()
