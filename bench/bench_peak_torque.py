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
Benchmark: peak input torque (speed_drive.peak_input_torque) in configurations/s.

On a 1000 x 1000 (offset, crank radius) grid of the paper design and on random designs
(offsets to 0.99 r1, random phases, crank radii and pivots, both speed signs), with the
small shaper's masses and loads. Baselines timed in the same run: pair_efforts' loop over
a subsample, and dense efforts (the revolution sampled at --dense points) on a subsample.
Medians of --repeats, on one thread and on all of numba's; the largest disagreement with
pair_efforts on the subsample.

    python3 dev.py run python bench/bench_peak_torque.py [--repeats 3] [--subsample 300]
"""

import argparse
import math
import time

import numba
import numpy as np

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import state
from qrm_ros.core.dynamics.speed_drive import pair_efforts, peak_input_torque

from bench_dynamics import median_seconds  # this folder: run as python bench/<name>.py


def random_designs(count, rng):
    r1 = rng.uniform(0.01, 0.05, count)
    h = rng.uniform(0.08, 0.2, count)
    r = h * rng.uniform(0.1, 0.95, count)
    geometry = Geometry(r1, r, h, rng.uniform(0.15, 0.4, count),
                        rng.uniform(-math.pi, math.pi, count))
    offset = r1 * rng.uniform(-0.99, 0.99, count)
    speed = rng.choice([-1.0, 1.0], count) * rng.uniform(1.0, 40.0, count)
    return geometry, offset, speed


def one(geometry, index):
    return Geometry(*(float(value if np.ndim(value) == 0 else np.ravel(value)[index])
                      for value in geometry.as_dict().values()))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--grid', type=int, default=1000)
    parser.add_argument('--random', type=int, default=1_000_000)
    parser.add_argument('--subsample', type=int, default=300)
    parser.add_argument('--dense', type=int, default=20_000)
    parser.add_argument('--repeats', type=int, default=3)
    args = parser.parse_args()
    mass = dyn.MassProperties.small_shaper()
    rng = np.random.default_rng(2026)

    start = time.perf_counter()
    peak_input_torque(Geometry.paper(), mass, dyn.Loads.small_shaper(), 0.01, 1.0)
    print(f'first call (import, load or compile of the kernel): '
          f'{time.perf_counter() - start:.2f} s')

    crank = np.linspace(0.02, 0.1, args.grid)[:, None]
    grid = Geometry(0.025, crank, 0.113)
    grid_offset = np.linspace(-0.0225, 0.0225, args.grid)[None, :]
    grid_loads = dyn.Loads(400.0, 20.0, 0.9 * float(np.min(grid.ram_stroke)))
    designs, offset, speed = random_designs(args.random, rng)
    loads = dyn.Loads(400.0, 20.0, 0.9 * float(np.min(designs.ram_stroke)))
    cases = (('grid', grid, grid_offset, 2.0 * math.pi, grid_loads, args.grid ** 2),
             ('random', designs, offset, speed, loads, args.random))
    for name, geometry, offsets, speeds, case_loads, count in cases:
        peaks = np.ravel(peak_input_torque(geometry, mass, case_loads, offsets, speeds))
        rates = {}
        for threads in (1, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(threads)
            seconds = median_seconds(lambda: peak_input_torque(geometry, mass, case_loads,
                                                               offsets, speeds), args.repeats)
            rates[threads] = count / seconds
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        rate = rates[1]
        flat_offset = np.ravel(np.broadcast_to(offsets, np.broadcast_shapes(
            np.shape(offsets), np.shape(crank) if name == 'grid' else ())))
        flat_speed = np.ravel(np.broadcast_to(speeds, flat_offset.shape))
        pick = rng.choice(count, args.subsample, replace=False)
        if name == 'grid':
            designs_of = [Geometry(0.025, float(crank[k // args.grid, 0]), 0.113)
                          for k in pick]
        else:
            designs_of = [one(geometry, k) for k in pick]

        def pair_loop():
            return [pair_efforts(design, mass, case_loads, float(flat_offset[k]),
                                 float(flat_speed[k])).peak_input_torque
                    for design, k in zip(designs_of, pick)]

        def dense_loop():
            theta = np.linspace(0.0, 2.0 * math.pi, args.dense, endpoint=False)
            for design, k in zip(designs_of, pick):
                motion = state(design, float(flat_offset[k]), theta, float(flat_speed[k]))
                load = dyn.ram_load_force(case_loads, motion.ram_position,
                                          motion.ram_velocity, design.ram_stroke)
                dyn.efforts(design, mass, float(flat_offset[k]), theta, float(flat_speed[k]),
                            external_ram_force=load)

        reference = np.array(pair_loop())
        pair_rate = args.subsample / median_seconds(pair_loop, args.repeats)
        dense_rate = args.subsample / median_seconds(dense_loop, args.repeats)
        safe = np.abs(flat_offset[pick]) <= 0.9 * np.array(
            [design.coupling_radius for design in designs_of])
        error = np.abs(peaks[pick] / reference - 1.0)
        threads = numba.config.NUMBA_NUM_THREADS
        print(f'{name} ({count} configurations): peak_input_torque {rates[threads]:.3g}/s on '
              f'{threads} threads, {rate:.3g}/s on one; pair_efforts {pair_rate:.3g}/s: ratio '
              f'{rate / pair_rate:.0f}x on one thread; dense efforts ({args.dense} samples) '
              f'{dense_rate:.3g}/s: ratio {rate / dense_rate:.0f}x; largest disagreement with '
              f'pair_efforts {np.max(error):.2g} ({np.max(error[safe]):.2g} within 0.9 r1)')


if __name__ == '__main__':
    main()
