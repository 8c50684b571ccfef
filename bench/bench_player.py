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
mcap_player's timing: arrival gaps at a subscriber against the recorded gaps, at 100 Hz.

A run of --seconds at 100 Hz is simulated (qrm_simulate's Simulation); its /joint_states are
played by mcap_player (a process, as users run it) to a raw subscription in this process,
which notes each arrival (perf_counter). The error of a message is its arrival gap to the one
before minus the recorded log-time gap. The baseline, in the same run and interleaved: a bare
rclpy publisher process sending the same bytes on the same schedule with a plain
time.sleep until each message's time. Medians over repeats of each one's median and 99th
percentile of |error|; goal for the player: median <= 0.1 ms, p99 <= 1 ms. Each sender
also says how late it handed each message over against its due time (the sender's own
timing, apart from DDS and the subscriber's scheduling).

    python3 dev.py run python bench/bench_player.py [--seconds 20] [--repeats 3]
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from qrm_ros.node.offline.offline_sim import Simulation
from qrm_ros.node.process.ros_isolation import isolate_ros_traffic
from qrm_ros.node.offline.scenario import scenario_from_mapping
from qrm_ros.recording.bag_reader import open_run

QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
# The senders' own timing line (mcap_player's last line says it the same way).
SENT = re.compile(r'sent after their recorded time by (-?[0-9.]+) ms \(median\), '
                  r'(-?[0-9.]+) ms')


def sleeping_publisher(path):
    """Publish the file's joint states at their times with plain sleeps (the baseline)."""
    rclpy.init()
    node = Node('sleeping_publisher')
    publisher = node.create_publisher(JointState, 'joint_states', QOS)
    messages = [(m.log_time, m.data) for m in open_run(path).messages('/joint_states')]
    while publisher.get_subscription_count() < 1:
        time.sleep(0.01)
    time.sleep(0.5)
    origin = time.perf_counter_ns()
    lateness = []
    for log_time, data in messages:
        due = origin + (log_time - messages[0][0])
        remaining = due - time.perf_counter_ns()
        if remaining > 0:
            time.sleep(remaining / 1e9)
        lateness.append(time.perf_counter_ns() - due)
        publisher.publish(data)
    publisher.wait_for_all_acked()
    lateness.sort()
    print(f'sent after their recorded time by {lateness[len(lateness) // 2] / 1e6:.3f} ms '
          f'(median), {_percentile(lateness, 0.99) / 1e6:.3f} ms (99th percentile)')
    node.destroy_node()
    rclpy.shutdown()


def _errors(arrivals, log_times):
    gaps = [b - a for a, b in zip(arrivals, arrivals[1:])]
    recorded = [b - a for a, b in zip(log_times, log_times[1:])]
    return sorted(abs(g - r) / 1e6 for g, r in zip(gaps, recorded))  # ms


def measure(kind, path, log_times):
    """Play the file with kind ('player' or 'sleep'); return |errors| in ms, sorted."""
    context = Context()
    rclpy.init(context=context)
    node = Node('timing_probe', context=context)
    arrivals = []
    node.create_subscription(JointState, 'joint_states',
                             lambda data: arrivals.append(time.perf_counter_ns()), QOS,
                             raw=True)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinning = threading.Thread(target=lambda: executor.spin(), daemon=True)
    spinning.start()
    if kind == 'player':
        process = subprocess.Popen(['mcap_player', path, '--start-paused', '--topics',
                                    'joint_states'], stdout=subprocess.PIPE, text=True)
        while node.count_publishers('/joint_states') < 1:
            time.sleep(0.01)
        client = node.create_client(Trigger, '/mcap_player/resume')
        client.wait_for_service()
        time.sleep(0.5)
        future = client.call_async(Trigger.Request())
        while not future.done():
            time.sleep(0.01)
    else:
        process = subprocess.Popen([sys.executable, __file__, '--sleeping-publisher', path],
                                   stdout=subprocess.PIPE, text=True)
    output, _ = process.communicate()
    sent = SENT.search(output)
    deadline = time.monotonic() + 10
    while len(arrivals) < len(log_times) and time.monotonic() < deadline:
        time.sleep(0.01)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=context)
    if len(arrivals) != len(log_times):
        print(f'{kind}: {len(arrivals)} of {len(log_times)} messages arrived')
    return _errors(arrivals, log_times), (float(sent[1]), float(sent[2])) if sent else None


def _percentile(values, fraction):
    return values[min(len(values) - 1, round(fraction * (len(values) - 1)))]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=20.0)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--sleeping-publisher', metavar='PATH', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.sleeping_publisher:
        return sleeping_publisher(args.sleeping_publisher)
    isolate_ros_traffic(os.environ)
    results = {'player': [], 'sleep': []}
    lateness = {'player': [], 'sleep': []}
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, 'run.mcap')
        Simulation(scenario_from_mapping({'duration': args.seconds}), path).run()
        log_times = [m.log_time for m in open_run(path).messages('/joint_states')]
        for repeat in range(args.repeats):
            for kind in (('player', 'sleep') if repeat % 2 == 0 else ('sleep', 'player')):
                errors, sent = measure(kind, path, log_times)
                results[kind].append((statistics.median(errors), _percentile(errors, 0.99),
                                      errors[-1]))
                if sent:
                    lateness[kind].append(sent)
                print(f'repeat {repeat + 1} {kind:6s}: |error| median '
                      f'{results[kind][-1][0]:.4f} ms, p99 {results[kind][-1][1]:.3f} ms, '
                      f'max {results[kind][-1][2]:.3f} ms; sent late by median '
                      f'{sent[0] if sent else float("nan"):.4f} ms, p99 '
                      f'{sent[1] if sent else float("nan"):.3f} ms', flush=True)
    for kind, rows in results.items():
        print(f'{kind:6s}: median of medians {statistics.median(r[0] for r in rows):.4f} ms, '
              f'median p99 {statistics.median(r[1] for r in rows):.3f} ms '
              f'(goal for the player: 0.1 ms, 1 ms)')
        if lateness[kind]:
            print(f'{kind:6s}: sent late (the sender alone) by a median of medians '
                  f'{statistics.median(r[0] for r in lateness[kind]):.4f} ms, median p99 '
                  f'{statistics.median(r[1] for r in lateness[kind]):.3f} ms')
    ratio = (statistics.median(r[0] for r in results['player'])
             / statistics.median(r[0] for r in results['sleep']))
    print(f'player / plain sleep, median error: {ratio:.3f}')


if __name__ == '__main__':
    sys.exit(main())
