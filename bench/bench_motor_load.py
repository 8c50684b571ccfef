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
Benchmark: how late 1 kHz motor-drive ticks come while the compiled forms load on a thread.

The first MotorStepper of a process loads qrm_ros.core.dynamics.drive_kernel (numba) on a thread of
its own. Each run is a fresh process that makes its first stepper and ticks it at 1 kHz (sleep
to the due time, the node's 0.1 ms GIL switch interval) for --ticks ticks; it prints how late
the ticks came (the tick's start past its due time) over the first 1000 ticks, while loading,
and the last 1000, and the same with the loading turned off (the baseline, in its own
process). A tick late by more than a period would be skipped by rcl's timer in the node.

    python3 dev.py run python bench/bench_motor_load.py [--runs 2] [--ticks 3000]
"""

import argparse
import math
import subprocess
import sys
import time


def _lateness(values):
    values = sorted(values)
    return (f'median {values[len(values) // 2] * 1e3:.3f} ms, '
            f'p99 {values[int(len(values) * 0.99)] * 1e3:.3f} ms, '
            f'max {values[-1] * 1e3:.3f} ms, over 0.5 ms: {sum(v > 5e-4 for v in values)}, '
            f'over 1 ms: {sum(v > 1e-3 for v in values)}')


def ticker(ticks, load):
    sys.setswitchinterval(1e-4)
    from qrm_ros.core.dynamics import chain as dyn
    from qrm_ros.core.kinematics.geometry import Geometry
    from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
    from qrm_ros.core.motor.motor_stepper import MotorStepper
    if not load:
        COMPILED_DRIVE_KERNEL.start_loading = lambda: None
    stepper = MotorStepper(Geometry.paper(), dyn.MassProperties.small_shaper(),
                           dyn.Loads.small_shaper(), dyn.MotorDrive.small_shaper(),
                           2 * math.pi, 0.01, 50.0, 0.01)
    late, loaded_at = [], None
    start = time.perf_counter()
    for tick in range(ticks):
        due = start + tick * 1e-3
        now = time.perf_counter()
        while now < due:
            if due - now > 2e-4:
                time.sleep(due - now - 1.5e-4)
            now = time.perf_counter()
        late.append(now - due)
        stepper.advance_to(tick * 1_000_000 + 1)
        stepper.efforts()
        if loaded_at is None and COMPILED_DRIVE_KERNEL.loaded.is_set():
            loaded_at = tick
    compiled = COMPILED_DRIVE_KERNEL.module is not None
    print(f'{"loading" if load else "baseline"}: compiled forms '
          f'{"loaded by tick " + str(loaded_at) if compiled else "not loaded"}')
    print(f'  first 1000 ticks: {_lateness(late[:1000])}')
    print(f'  last 1000 ticks:  {_lateness(late[-1000:])}', flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--runs', type=int, default=2)
    parser.add_argument('--ticks', type=int, default=3000)
    parser.add_argument('--ticker', choices=('load', 'baseline'), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.ticker:
        ticker(args.ticks, args.ticker == 'load')
        return
    for _ in range(args.runs):
        for mode in ('load', 'baseline'):
            subprocess.run([sys.executable, __file__, '--ticks', str(args.ticks), '--ticker',
                            mode], check=True)


if __name__ == '__main__':
    main()
