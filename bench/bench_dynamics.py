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
Benchmark: vectorised efforts (samples/s) and the per-tick cost of the motor stepper.

efforts' target is >= 1e6 samples/s; MotorStepper.advance_to at 1 kHz is compared with
ShaperStepper's, both measured in this run.

    python3 dev.py run python bench/bench_dynamics.py [--samples 1000000] [--ticks 5000]
"""

import argparse
import math
import statistics
import time

import numpy as np

from qrm_ros import dynamics as dyn
from qrm_ros.kinematics import Geometry
from qrm_ros.motor_drive import MotorStepper
from qrm_ros.stepping import ShaperStepper


def median_seconds(function, repeats):
    timings = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        timings.append(time.perf_counter() - start)
    return statistics.median(timings)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--samples', type=int, default=1_000_000)
    parser.add_argument('--ticks', type=int, default=5000)
    parser.add_argument('--repeats', type=int, default=3)
    args = parser.parse_args()
    geometry = Geometry.paper()
    mass, loads = dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper()
    angles = np.linspace(0.0, 20 * math.pi, args.samples)
    seconds = median_seconds(lambda: dyn.efforts(geometry, mass, 0.01, angles, 2 * math.pi,
                                                 external_ram_force=100.0), args.repeats)
    print(f'efforts: {args.samples / seconds:.3g} samples/s (target >= 1e6)')

    def ticks(stepper):
        def run():
            stepper.reset(2 * math.pi, 0.01)
            for tick in range(args.ticks):
                stepper.advance_to(tick * 1_000_000)
        return run

    speed = median_seconds(ticks(ShaperStepper(geometry, 2 * math.pi, 0.01, 50.0, 0.01)),
                           args.repeats) / args.ticks
    motor = median_seconds(ticks(MotorStepper(geometry, mass, loads,
                                              dyn.MotorDrive.small_shaper(), 2 * math.pi,
                                              0.01, 50.0, 0.01)), args.repeats) / args.ticks
    print(f'advance_to at 1 kHz: ShaperStepper {speed * 1e6:.1f} us/tick, MotorStepper '
          f'{motor * 1e6:.1f} us/tick, ratio {motor / speed:.2f}')


if __name__ == '__main__':
    main()
