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
Benchmark: qrm_analyze's streamed analysis of a 1-hour and an 8-hour run, memory and time.

Writes synthetic 100 Hz runs (bench_analysis' writer: the kinematics core's states, an
offset held 5 minutes at a time, cycling through seven offsets), then runs, interleaved and
each in a fresh process: the streamed analysis (``streamed_run.analyse_file``: read, check,
decode, segment, measure; what qrm_analyze does) and the bare baseline, rosbags' AnyReader
reading and deserializing the same joint states. Prints medians of each process's peak
memory (VmHWM) and of its time (imports excluded), and the ratios: 8 h against 1 h in
memory (target <= 1.2x, and < 300 MB) and in time per hour (<= 1.1x), and the analysis
against the bare read (<= 1.0x). With --main, also the main job's report (``qrm_main.report``:
the streamed analysis, its figures and the offset tour, which read only what they draw):
its peak memory at each length.

    python3 dev.py run python bench/bench_streaming.py [--hours 1 8] [--repeats 3] [--main]
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

CHILD = '''
import json, sys, time
from pathlib import Path
which, path = sys.argv[1:]
if which == 'ours':
    from qrm_ros.analysis.streamed_run import analyse_file
    start = time.perf_counter()
    pairs = sum(row['stroke_pairs'] for row in analyse_file(path, progress_stream=None).rows)
elif which == 'main':  # the main job's report: the analysis, figures and offset tour
    import contextlib, io, json as results, os, tempfile
    from qrm_ros.cli import qrm_main
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder, contextlib.redirect_stdout(io.StringIO()):
        qrm_main.report(path, folder)
        with open(os.path.join(folder, 'results.json')) as document:
            pairs = sum(s['stroke_pairs'] for s in results.load(document)['segments'])
else:
    from rosbags.highlevel import AnyReader
    start = time.perf_counter()
    pairs = 0
    with AnyReader([Path(path)]) as reader:
        connections = [c for c in reader.connections if c.topic == '/joint_states']
        for connection, _, raw in reader.messages(connections=connections):
            reader.deserialize(raw, connection.msgtype)
            pairs += 1
seconds = time.perf_counter() - start
with open('/proc/self/status') as status:  # the peak of this process, not its parent's
    peak = next(int(line.split()[1]) * 1024 for line in status if line.startswith('VmHWM:'))
print(json.dumps({'seconds': seconds, 'count': pairs, 'peak': peak}))
'''


def measure(which, path):
    """Run one analysis or bare read in a fresh process; return (s, peak bytes, count)."""
    done = subprocess.run([sys.executable, '-c', CHILD, which, path], stdout=subprocess.PIPE,
                          text=True, check=True)
    result = json.loads(done.stdout)
    return result['seconds'], result['peak'], result['count']


def _median(values):
    return statistics.median(values)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--hours', type=float, nargs='+', default=[1.0, 8.0],
                        help='run lengths [h]; the first is the reference')
    parser.add_argument('--repeats', type=int, default=3, help='interleaved repeats')
    parser.add_argument('--main', action='store_true',
                        help="also the main job's report (qrm_main: the analysis, its figures "
                             'and offset tour): its peak memory at each length')
    args = parser.parse_args()
    kinds = ('bare', 'ours') + (('main',) if args.main else ())
    with tempfile.TemporaryDirectory() as folder:
        paths = {}
        for hours in args.hours:
            paths[hours] = os.path.join(folder, f'{hours:g}h.mcap')
            start = time.perf_counter()
            messages = write_synthetic_run(paths[hours], hours * 3600.0, hold=HOLD, twist=False)
            print(f'{hours:g} h: wrote {messages} joint states '
                  f'({os.path.getsize(paths[hours]) / 1e6:.0f} MB) in '
                  f'{time.perf_counter() - start:.0f} s', flush=True)
        found = {(hours, who): [] for hours in args.hours for who in kinds}
        for repeat in range(args.repeats):
            for hours in args.hours:
                for who in (kinds[::-1] if repeat % 2 else kinds):
                    seconds, peak, count = measure(who, paths[hours])
                    found[hours, who].append((seconds, peak))
                    print(f'repeat {repeat + 1}, {hours:g} h, {who}: {seconds:.2f} s, peak '
                          f'{peak / 1e6:.0f} MB ({count} {"read" if who == "bare" else "pairs"})',
                          flush=True)
    reference = args.hours[0]
    base_time = _median([s for s, _ in found[reference, 'ours']]) / reference
    base_peak = _median([p for _, p in found[reference, 'ours']])
    for hours in args.hours:
        ours = found[hours, 'ours']
        bare = found[hours, 'bare']
        seconds, peak = _median([s for s, _ in ours]), _median([p for _, p in ours])
        ratios = [s / b for (s, _), (b, _) in zip(ours, bare)]
        print(f'{hours:g} h: analysis median {seconds:.2f} s ({seconds / hours:.2f} s per hour, '
              f'{seconds / hours / base_time:.2f}x the {reference:g} h run\'s; target <= 1.1x), '
              f'peak {peak / 1e6:.0f} MB ({peak / base_peak:.2f}x; targets <= 1.2x and < 300 MB);'
              f' bare read {_median([b for b, _ in bare]):.2f} s, peak '
              f'{_median([p for _, p in bare]) / 1e6:.0f} MB; ratio analysis / bare read median '
              f'{_median(ratios):.2f}x (min {min(ratios):.2f}, max {max(ratios):.2f}; target '
              '<= 1.0x)')
    if args.main:
        main_peak = _median([p for _, p in found[reference, 'main']])
        for hours in args.hours:
            runs = found[hours, 'main']
            peak = _median([p for _, p in runs])
            print(f'{hours:g} h: main job report (analysis, figures, tour) median '
                  f'{_median([s for s, _ in runs]):.2f} s, peak {peak / 1e6:.0f} MB '
                  f'({peak / main_peak:.2f}x the {reference:g} h run\'s)')


if __name__ == '__main__':
    main()
