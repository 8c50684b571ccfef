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
Benchmark: shaper_sim against a bare rclpy timer publishing a JointState of the same size.

    python3 dev.py run python bench/bench_node.py [--repeat 3] [--window 1.5]

Both run as their own processes, one after the other in the same run, at each publish rate;
this process subscribes to joint_states and counts missed ticks from the stamps (a gap of
k periods is k - 1 missed ticks). A rate is sustained when at most 1 % of its ticks are
missed over the window; the highest rate reported is the highest up to which every tested
rate was sustained. CPU is the publisher's user + system time over the window (/proc),
in percent of one core. Prints each run and the medians over runs. Not a test: no
thresholds are asserted (targets: max rate >= 0.9 x bare, CPU at 1 kHz <= 1.2 x bare).
"""

import argparse
from array import array
import os
import shutil
import statistics
import subprocess
import sys
import time

from qrm_ros.ros_isolation import isolate_ros_traffic

RATES = [100.0, 200.0, 500.0, 1000.0, 2000.0, 3000.0, 5000.0]
SUSTAINED_MISSED_FRACTION = 0.01


def bare_main(rate):
    """Publish a 5-joint JointState at `rate` from a plain rclpy timer."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from sensor_msgs.msg import JointState

    rclpy.init()
    node = rclpy.create_node('bare_publisher')
    publisher = node.create_publisher(JointState, 'joint_states', 10)
    message = JointState(name=['input_shaft_joint', 'flywheel_joint', 'lever_joint',
                               'ram_joint', 'coupling_offset_joint'])
    clock = node.get_clock()

    def tick():
        now = clock.now()
        seconds = now.nanoseconds * 1e-9
        message.header.stamp = now.to_msg()
        message.position = array('d', (seconds, seconds, seconds, seconds, seconds))
        message.velocity = array('d', (1.0, 1.0, 1.0, 1.0, 1.0))
        publisher.publish(message)

    node.create_timer(1.0 / rate, tick)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def cpu_seconds(pid):
    with open(f'/proc/{pid}/stat') as handle:
        fields = handle.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def measure(command, rate, window, probe):
    """Start a publisher, measure missed ticks and CPU over `window` seconds, stop it."""
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        probe.stamps.clear()
        deadline = time.monotonic() + 20.0
        while len(probe.stamps) < 10:
            probe.spin_once()
            if time.monotonic() > deadline:
                raise RuntimeError(f'no joint states from {command[0]}')
        time.sleep(0.2)  # past start-up
        probe.drain()
        probe.stamps.clear()
        cpu_start, wall_start = cpu_seconds(process.pid), time.monotonic()
        while time.monotonic() - wall_start < window:
            probe.spin_once()
        cpu = (cpu_seconds(process.pid) - cpu_start) / (time.monotonic() - wall_start)
        probe.drain()
        stamps = list(probe.stamps)
    finally:
        process.send_signal(2)
        try:
            process.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    period = 1e9 / rate
    missed = sum(max(0, round((b - a) / period) - 1) for a, b in zip(stamps, stamps[1:]))
    expected = max(1, round((stamps[-1] - stamps[0]) / period) + 1) if stamps else 1
    return missed / expected, 100.0 * cpu


class Probe:
    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile
        from sensor_msgs.msg import JointState

        rclpy.init()
        self.node = rclpy.create_node('bench_probe')
        self.stamps = []
        self.node.create_subscription(
            JointState, 'joint_states',
            lambda m: self.stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec),
            QoSProfile(depth=10000))
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def spin_once(self):
        self.executor.spin_once(timeout_sec=0.01)

    def drain(self):
        for _ in range(50):
            self.executor.spin_once(timeout_sec=0.002)


def one_run(window, probe):
    shaper = shutil.which('shaper_sim')
    shaper = shaper or os.path.join(os.path.dirname(sys.executable), 'shaper_sim')
    results = {}
    for rate in RATES:
        for kind, command in (
                ('node', [shaper, '--ros-args', '-p', f'publish_rate:={rate}']),
                ('bare', [sys.executable, os.path.abspath(__file__), '--bare', str(rate)])):
            results[kind, rate] = measure(command, rate, window, probe)
            missed, cpu = results[kind, rate]
            print(f'  {kind} {rate:6.0f} Hz: missed {100 * missed:5.2f} % of ticks, '
                  f'CPU {cpu:5.1f} %', flush=True)
    summary = {}
    for kind in ('node', 'bare'):
        # The highest rate up to which every tested rate was sustained.
        summary[kind, 'max_rate'] = 0.0
        for rate in RATES:
            if results[kind, rate][0] > SUSTAINED_MISSED_FRACTION:
                break
            summary[kind, 'max_rate'] = rate
        summary[kind, 'cpu_100'] = results[kind, 100.0][1]
        summary[kind, 'cpu_1000'] = results[kind, 1000.0][1]
    return summary


def report(summary, label):
    def ratio(name):
        bare = summary['bare', name]
        return summary['node', name] / bare if bare else float('inf')
    print(f'{label}: highest rate without missed ticks (<= 1 % missed): node '
          f'{summary["node", "max_rate"]:.0f} Hz, bare {summary["bare", "max_rate"]:.0f} Hz, '
          f'node/bare {ratio("max_rate"):.2f}')
    print(f'{label}: CPU at 100 Hz: node {summary["node", "cpu_100"]:.1f} %, bare '
          f'{summary["bare", "cpu_100"]:.1f} %, node/bare {ratio("cpu_100"):.2f}')
    print(f'{label}: CPU at 1 kHz: node {summary["node", "cpu_1000"]:.1f} %, bare '
          f'{summary["bare", "cpu_1000"]:.1f} %, node/bare {ratio("cpu_1000"):.2f}',
          flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--repeat', type=int, default=3, help='runs (medians reported)')
    parser.add_argument('--window', type=float, default=2.0, help='seconds per measurement')
    parser.add_argument('--bare', type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.bare:
        return bare_main(args.bare)
    isolate_ros_traffic(os.environ)
    probe = Probe()
    runs = []
    for index in range(args.repeat):
        print(f'run {index + 1}/{args.repeat} ({os.cpu_count()} CPUs, window {args.window} s)',
              flush=True)
        runs.append(one_run(args.window, probe))
        report(runs[-1], f'run {index + 1}')
    median = {key: statistics.median(run[key] for run in runs) for key in runs[0]}
    report(median, f'median of {len(runs)}')


if __name__ == '__main__':
    sys.exit(main())
