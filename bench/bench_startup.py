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
Benchmark: how long each command takes to load, against a bare rclpy node's imports.

A command loads only what it uses: the recorder, above all, must be recording as soon as a
bare subscriber started beside it would be. Each sample is a fresh interpreter that imports
one command's module (what its console script imports before main runs) and prints the
time the import took; the baseline imports rclpy and rclpy.node, interleaved with the rest.
Prints the median (and min-max) over the repeats in milliseconds and the ratio of each
median to the baseline's, and which heavy libraries each command loads.

    python3 dev.py run python bench/bench_startup.py [--repeats 15]
"""

import argparse
import json
import statistics
import subprocess
import sys

from qrm_ros.cli import entry_points

# What each console script imports before its main runs: qrm_ros.cli.<command>
# (qrm_ros.cli.entry_points), after the baseline.
COMMANDS = {'rclpy (baseline)': 'rclpy, rclpy.node',
            **{command: f'qrm_ros.cli.{command}' for command in entry_points.__all__}}
HEAVY = ('scipy', 'numba', 'matplotlib')
_PROBE = ('import sys, time\n'
          'start = time.perf_counter()\n'
          'import {modules}\n'
          'seconds = time.perf_counter() - start\n'
          'import json\n'
          'print(json.dumps([seconds, [m for m in {heavy!r} if m in sys.modules]]))\n')


def load_time(modules):
    """Return (seconds, heavy libraries loaded) of importing modules in a new interpreter."""
    output = subprocess.run([sys.executable, '-c', _PROBE.format(modules=modules, heavy=HEAVY)],
                            capture_output=True, text=True, check=True).stdout
    seconds, heavy = json.loads(output)
    return seconds, heavy


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--repeats', type=int, default=15)
    args = parser.parse_args()
    samples = {name: [] for name in COMMANDS}
    loaded = {}
    for _ in range(args.repeats):  # interleaved: every command meets the same machine
        for name, modules in COMMANDS.items():
            seconds, loaded[name] = load_time(modules)
            samples[name].append(seconds * 1e3)
    baseline = statistics.median(samples['rclpy (baseline)'])
    print(f'{"command":<18} {"median ms":>10} {"min-max ms":>15} {"x rclpy":>8}  loads')
    for name, times in samples.items():
        median = statistics.median(times)
        spread = f'{min(times):.0f}-{max(times):.0f}'
        print(f'{name:<18} {median:>10.0f} {spread:>15} {median / baseline:>8.2f}  '
              f'{", ".join(loaded[name]) or "-"}')


if __name__ == '__main__':
    main()
