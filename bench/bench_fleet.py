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
Benchmark: a fleet of eight recordings, one process against a local pool and a Dask cluster.

Writes one synthetic 100 Hz run (bench_analysis' writer, an offset held 5 minutes at a time)
and links it under eight names, then analyses the eight as qrm_analyze's fleet does,
interleaved, several times, each time in a fresh process as a user's qrm_analyze is (its own
imports not timed, the same in every mode): one after the other (--jobs 1), in a pool of two
local processes (--jobs 2; their start-up counted, as a user waits for it), and on a
``distributed.LocalCluster`` of two single-threaded worker processes on loopback (started
once, as a user's cluster already runs). Prints medians and the ratios: the pool's speed-up
over one process (target >= 1.8x on 2 cores) and the cluster's time against the pool's
(target <= 1.2x); and checks that the three give the same fleet report.

    python3 dev.py run python bench/bench_fleet.py [--hours 1] [--files 8] [--repeats 3]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from bench_analysis import write_synthetic_run

HOLD = 300.0  # s at each offset

# One qrm_analyze of the fleet: its imports first, then the timed analysis.
CHILD = '''
import json, resource, sys, time
from qrm_ros.analysis import fleet


def cpu():  # s of CPU of this process and its (finished) children
    return sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
               for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))


mode, scheduler, paths = sys.argv[1], sys.argv[2], sys.argv[3:]
if mode == 'cluster':
    import distributed  # noqa: F401 - an import, as the other modes' are, not timed
method = fleet.start_method()
start, start_cpu = time.perf_counter(), cpu()
if mode == 'serial':
    results = fleet.run_serially(paths, None)
elif mode == 'pool':
    results = fleet.run_in_pool(paths, None, 2)
else:
    results = fleet.run_on_cluster(paths, None, scheduler)
results = fleet.in_file_order(paths, results)
seconds = time.perf_counter() - start
print(json.dumps({'seconds': seconds, 'cpu': cpu() - start_cpu, 'method': method,
                  'report': fleet.fleet_document(results)}))
'''


def measure(mode, paths, scheduler=''):
    """
    Analyse the fleet in a fresh process; return (s, CPU s, the fleet report, start method).

    The CPU time is the process's and its workers' (a cluster's workers are not counted).
    """
    done = subprocess.run([sys.executable, '-c', CHILD, mode, scheduler, *paths],
                          stdout=subprocess.PIPE, text=True, check=True)
    result = json.loads(done.stdout)
    return result['seconds'], result['cpu'], json.dumps(result['report']), result['method']


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--hours', type=float, default=1.0, help='length of each run [h]')
    parser.add_argument('--files', type=int, default=8, help='recordings in the fleet')
    parser.add_argument('--repeats', type=int, default=3, help='interleaved repeats')
    args = parser.parse_args()
    from distributed import LocalCluster
    with tempfile.TemporaryDirectory() as folder:
        first = os.path.join(folder, 'run00.mcap')
        start = time.perf_counter()
        write_synthetic_run(first, args.hours * 3600.0, hold=HOLD, twist=False)
        print(f'wrote a {args.hours:g} h run in {time.perf_counter() - start:.0f} s',
              flush=True)
        paths = [first]
        for number in range(1, args.files):
            paths.append(os.path.join(folder, f'run{number:02d}.mcap'))
            os.link(first, paths[-1])
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host='127.0.0.1',
                          dashboard_address=None) as cluster:
            modes = {'one process': ('serial', ''), 'pool of 2': ('pool', ''),
                     'dask cluster of 2': ('cluster', cluster.scheduler_address)}
            times = {mode: [] for mode in modes}
            cpus = {mode: [] for mode in modes}
            reports = {}
            for repeat in range(args.repeats):
                order = list(modes) if repeat % 2 == 0 else list(reversed(modes))
                for mode in order:
                    seconds, cpu, reports[mode], method = measure(modes[mode][0], paths,
                                                                  modes[mode][1])
                    times[mode].append(seconds)
                    cpus[mode].append(cpu)
                    started = f', workers started by {method}' if mode == 'pool of 2' else ''
                    print(f'repeat {repeat + 1}, {mode}: {seconds:.2f} s ({cpu:.2f} s of CPU'
                          f'{started})', flush=True)
    same = len(set(reports.values())) == 1
    median = {mode: statistics.median(values) for mode, values in times.items()}
    speedups = [s / p for s, p in zip(times['one process'], times['pool of 2'])]
    cluster_ratios = [d / p for d, p in zip(times['dask cluster of 2'], times['pool of 2'])]
    print(f'{args.files} runs of {args.hours:g} h: ' + ', '.join(
        f'{mode} median {value:.2f} s' for mode, value in median.items()))
    print(f'pool of 2 speed-up over one process: median {statistics.median(speedups):.2f}x '
          f'(min {min(speedups):.2f}, max {max(speedups):.2f}; target >= 1.8x)')
    print(f'dask cluster / pool of 2: median {statistics.median(cluster_ratios):.2f}x '
          f'(min {min(cluster_ratios):.2f}, max {max(cluster_ratios):.2f}; target <= 1.2x)')
    # What the pool would reach on two idle cores: all its CPU shared evenly by them.
    bounds = [s / (p / 2) for s, p in zip(cpus['one process'], cpus['pool of 2'])]
    print(f'CPU: one process median {statistics.median(cpus["one process"]):.2f} s, pool of 2 '
          f'{statistics.median(cpus["pool of 2"]):.2f} s: on two idle cores at most '
          f'{statistics.median(bounds):.2f}x (min {min(bounds):.2f}, max {max(bounds):.2f})')
    print(f'the same fleet report from all three: {same}')
    with open('/proc/loadavg') as load:
        print(f'load average after the run (1, 5, 15 min): {" ".join(load.read().split()[:3])}')


if __name__ == '__main__':
    main()
