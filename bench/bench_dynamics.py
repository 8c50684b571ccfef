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
Benchmark: vectorised efforts (samples/s), the per-tick cost of the motor stepper, pair_efforts.

efforts' target is >= 1e6 samples/s. A node tick at 1 kHz is timed as the node spends it:
the speed drive's ShaperStepper.advance_to plus the efforts of the prescribed motion, the
motor drive's MotorStepper.advance_to plus its efforts(); advance_to alone is timed too, and
the motor tick once more with the stepper's right-hand side and efforts in their Python form
(before the compiled form has loaded, or without numba). Both ticks are timed again while the
stroke screw moves (the whole chain at the moving crank radius, the node's efforts with the
screw's force). The drives run in turns, each
repeat one second of ticks, and the medians of the repeats are compared (the machine is
shared: only ratios within one run mean much).

    python3 dev.py run python bench/bench_dynamics.py [--samples 1000000] [--ticks 1000]
"""

import argparse
import math
import statistics
import time

import numpy as np

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.dynamics.speed_drive import pair_efforts
from qrm_ros.core.stepping.stepping import ShaperStepper
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp
from qrm_ros.core.dynamics.stroke_efforts import (efforts_with_stroke_screw,
                                                  lever_radius_coefficient)


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
    parser.add_argument('--ticks', type=int, default=1000)
    parser.add_argument('--repeats', type=int, default=9)
    args = parser.parse_args()
    geometry = Geometry.paper()
    mass, loads = dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper()
    angles = np.linspace(0.0, 20 * math.pi, args.samples)
    seconds = median_seconds(lambda: dyn.efforts(geometry, mass, 0.01, angles, 2 * math.pi,
                                                 external_ram_force=100.0), 3)
    print(f'efforts: {seconds / args.samples * 1e9:.0f} ns/sample, '
          f'{args.samples / seconds:.3g} samples/s (target >= 1e6)')

    def moving_stroke():
        return StrokeRamp(geometry, 0.07, float(geometry.ram_stroke), 0.02)

    def speed_efforts(stepper, motion):
        load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                                  geometry.ram_stroke)
        return dyn.efforts(geometry, mass, stepper.offset, stepper.input_angle,
                           stepper.input_speed, stepper.input_acceleration,
                           stepper.offset_rate, 0.0, load)

    def motor_efforts(stepper, motion):
        return stepper.efforts()

    def moving_speed_efforts(stepper, motion):
        load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                                  geometry.ram_stroke)
        return efforts_with_stroke_screw(
            stepper.geometry, mass, stepper.offset, stepper.input_angle, stepper.input_speed,
            stepper.input_acceleration, stepper.offset_rate, 0.0, load,
            *stepper.stroke.crank_radius_rates())

    def moving_motor_efforts(stepper, motion):
        efforts = stepper.efforts()
        return efforts, efforts.lever_torque * lever_radius_coefficient(
            stepper.geometry, motion.flywheel_angle)

    def ticks(stepper, efforts, stroke_command=None):
        def run():
            stepper.reset(2 * math.pi, 0.01, stroke_length=float(geometry.ram_stroke))
            if stroke_command is not None:  # 0.02 m/s: moving throughout the ticks
                stepper.set_stroke_command(stroke_command)
            for tick in range(args.ticks):
                motion = stepper.advance_to(tick * 1_000_000)
                if efforts is not None:
                    efforts(stepper, motion)
        return run

    runs = {
        'speed advance_to': ticks(ShaperStepper(geometry, 2 * math.pi, 0.01, 50.0, 0.01),
                                  None),
        'motor advance_to': ticks(MotorStepper(geometry, mass, loads,
                                               dyn.MotorDrive.small_shaper(), 2 * math.pi,
                                               0.01, 50.0, 0.01), None),
        'speed tick': ticks(ShaperStepper(geometry, 2 * math.pi, 0.01, 50.0, 0.01),
                            speed_efforts),
        'motor tick': ticks(MotorStepper(geometry, mass, loads, dyn.MotorDrive.small_shaper(),
                                         2 * math.pi, 0.01, 50.0, 0.01), motor_efforts),
        'speed tick, stroke moving': ticks(
            ShaperStepper(geometry, 2 * math.pi, 0.01, 50.0, 0.01, moving_stroke()),
            moving_speed_efforts, 0.16),
        'motor tick, stroke moving': ticks(
            MotorStepper(geometry, mass, loads, dyn.MotorDrive.small_shaper(), 2 * math.pi,
                         0.01, 50.0, 0.01, moving_stroke()), moving_motor_efforts, 0.16),
    }
    # The stepper's compiled right-hand side loads on a thread of its own (once per process);
    # the ticks are timed once it is there, and once in its Python form for comparison.
    start = time.perf_counter()
    COMPILED_DRIVE_KERNEL.loaded.wait(60.0)
    compiled = COMPILED_DRIVE_KERNEL.module
    print(f'motor stepper: compiled right-hand side and efforts '
          f'{"loaded" if compiled is not None else "unavailable (no numba)"}, waited '
          f'{time.perf_counter() - start:.2f} s after the first stepper')
    runs['motor tick (Python form)'] = runs['motor tick']
    timings = {name: [] for name in runs}
    for _ in range(args.repeats):
        for name, run in runs.items():
            COMPILED_DRIVE_KERNEL.module = None if name.endswith('(Python form)') else compiled
            start = time.perf_counter()
            run()
            timings[name].append((time.perf_counter() - start) / args.ticks * 1e6)
    median = {name: statistics.median(values) for name, values in timings.items()}
    for kind in ('advance_to', 'tick'):
        speed, motor = median[f'speed {kind}'], median[f'motor {kind}']
        print(f'{kind} at 1 kHz (medians of {args.repeats}): speed drive {speed:.1f} us, '
              f'motor drive {motor:.1f} us, ratio {motor / speed:.2f}, motor adds '
              f'{(motor - speed) / 10:.1f} % of a core')
    speed, motor = median['speed tick, stroke moving'], median['motor tick, stroke moving']
    print(f'tick while the stroke moves (medians of {args.repeats}): speed drive {speed:.1f} '
          f'us, motor drive {motor:.1f} us, ratio {motor / speed:.2f}; the motor tick '
          f'{motor / median["motor tick"]:.2f} times its tick at a still stroke')
    python = median['motor tick (Python form)']
    print(f'motor tick with the Python right-hand side and efforts: {python:.1f} us, ratio '
          f'{python / median["speed tick"]:.2f} to the speed tick')
    offsets = np.linspace(-0.02, 0.02, 9)
    seconds = median_seconds(lambda: [pair_efforts(geometry, mass, loads, offset, 2 * math.pi)
                                      for offset in offsets], 3) / offsets.size
    print(f'pair_efforts: {seconds * 1e3:.2f} ms per call (mean over {offsets.size} offsets '
          '-0.02..0.02 m, median of 3 repeats)')


if __name__ == '__main__':
    main()
