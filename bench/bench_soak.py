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
Soak benchmark: mcap_recorder for --minutes at 2 kHz aggregate, losses and memory growth.

The publisher and the parallel subscriber are bench_recorder's (JointState and TwistStamped
at --rate Hz each; a bare raw subscription that counts). Messages lost are counted against
what was offered and against the parallel subscriber (target 0 for both); the recorder's
RSS is sampled every --sample seconds and its growth reported from the first sample after
--warm-up seconds to the end, with the recorder's CPU over the whole run.

    python3 dev.py run python bench/bench_soak.py [--minutes 10] [--rate 1000]
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

from bench_recorder import recorder_command
from process_stats import cpu_seconds, rss_bytes
from qrm_ros.node.process.ros_isolation import isolate_ros_traffic

HERE = os.path.dirname(os.path.abspath(__file__))
BENCH_RECORDER = os.path.join(HERE, 'bench_recorder.py')


def _recorded_count(path):
    """Messages in the finished file, from its statistics record (checked by the tests)."""
    from mcap.reader import make_reader
    with open(path, 'rb') as handle:
        return make_reader(handle).get_summary().statistics.message_count


def _joint_state_gaps(path):
    """Find the runs of lost joint states: (count, largest run, log times of the 5 largest)."""
    from mcap.reader import make_reader
    import rclpy.serialization
    from sensor_msgs.msg import JointState
    runs, previous = [], None
    with open(path, 'rb') as handle:
        for _, channel, message in make_reader(handle).iter_messages(topics=['/joint_states']):
            state = rclpy.serialization.deserialize_message(message.data, JointState)
            sequence = round(state.position[0] * 1e3)  # the publisher's message number
            if previous is not None and sequence > previous + 1:
                runs.append((sequence - previous - 1, message.log_time))
            previous = sequence
    runs.sort(reverse=True)
    return len(runs), (runs[0][0] if runs else 0), runs[:5]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--minutes', type=float, default=10.0,
                        help='publishing time [min] (default 10)')
    parser.add_argument('--rate', type=float, default=1000.0,
                        help='publish rate per topic [Hz] (default 1000: 2 kHz aggregate)')
    parser.add_argument('--sample', type=float, default=10.0,
                        help='RSS sampling period [s] (default 10)')
    parser.add_argument('--warm-up', type=float, default=20.0,
                        help='time before the first RSS sample counts [s] (default 20)')
    args = parser.parse_args()
    if not (args.minutes > 0 and args.rate > 0 and args.sample > 0 and args.warm_up >= 0):
        parser.error('--minutes, --rate and --sample must be > 0, --warm-up >= 0')
    env = dict(os.environ)
    isolate_ros_traffic(env)
    seconds = args.minutes * 60.0
    with tempfile.TemporaryDirectory() as folder:
        output = os.path.join(folder, 'soak.mcap')
        log = open(os.path.join(folder, 'recorder.log'), 'w')
        recorder = subprocess.Popen(recorder_command(output), stdout=log, stderr=log, env=env)
        bare = subprocess.Popen([sys.executable, BENCH_RECORDER, '--floor'],
                                stdout=subprocess.PIPE, text=True, env=env)
        publisher = subprocess.Popen([sys.executable, BENCH_RECORDER, '--publish',
                                      str(seconds), str(args.rate)],
                                     stdout=subprocess.PIPE, text=True, env=env)
        line = publisher.stdout.readline().strip()
        assert line == 'started', line
        started = time.monotonic()
        cpu_start = cpu_seconds(recorder.pid)
        samples = []  # (seconds since start, RSS bytes)
        while publisher.poll() is None and time.monotonic() - started < seconds:
            time.sleep(min(args.sample, max(0.0, seconds - (time.monotonic() - started))))
            samples.append((time.monotonic() - started, rss_bytes(recorder.pid)))
            print(f'{samples[-1][0]:7.0f} s: recorder RSS {samples[-1][1] / 2**20:.1f} MiB',
                  flush=True)
        offered = int(publisher.stdout.readline().split()[1])
        cpu_used = cpu_seconds(recorder.pid) - cpu_start
        wall = time.monotonic() - started
        publisher.wait(60)
        for process in (recorder, bare):
            process.send_signal(signal.SIGINT)
        assert recorder.wait(120) == 0, open(log.name).read()
        received = int(bare.communicate(timeout=60)[0].split()[-1])
        recorded = _recorded_count(output)
        size = os.path.getsize(output)
        gaps = _joint_state_gaps(output) if recorded < offered else None
    counted = [rss for t, rss in samples if t >= args.warm_up] or [samples[-1][1]]
    print(f'\nsoak: {args.minutes:g} min at 2 x {args.rate:g} Hz: offered {offered}, recorded '
          f'{recorded} (lost {offered - recorded}), parallel subscriber {received} (lost '
          f'{offered - received}); file {size / 2**20:.1f} MiB')
    if gaps:
        start_ns = time.time_ns() - int((time.monotonic() - started) * 1e9)
        print(f'joint states lost in {gaps[0]} runs, the longest {gaps[1]} messages; largest '
              'runs (messages, s after start): ' + ', '.join(
                  f'{count} at {(log_ns - start_ns) / 1e9:.0f} s' for count, log_ns in gaps[2]))
    print(f'recorder RSS {counted[0] / 2**20:.1f} MiB after {args.warm_up:g} s -> '
          f'{counted[-1] / 2**20:.1f} MiB at the end (growth '
          f'{(counted[-1] - counted[0]) / 2**20:+.1f} MiB, max '
          f'{max(counted) / 2**20:.1f} MiB); recorder CPU {100 * cpu_used / wall:.1f} % of '
          f'one core')
    return 0


if __name__ == '__main__':
    sys.exit(main())
