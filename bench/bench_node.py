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

    python3 dev.py run python bench/bench_node.py [--repeat 5] [--window 2] [--allow-busy]

Every publisher runs as its own process; this process subscribes to joint_states and counts,
from the stamps, missed ticks (due but never published) and late ones (a gap of k periods
between two stamps is k - 1 late ticks: what this benchmark called missed until 2026-11-24).
Variants, measured interleaved (each repeat visits every rate and variant, in a rotated
order, so slow drifts of the machine hit all alike):
  node         shaper_sim as shipped (rclpy's EventsExecutor), default parameters
  node-single  the same on rclpy's SingleThreadedExecutor (QRM_ROS_EXECUTOR=single)
  node-cut     as shipped, speed drive, with the main job's default cutting load
               (dynamics.Loads.small_shaper)
  node-motor   as shipped, drive:=motor, with that load (issue 9: <= 1.3 x node-cut)
  node-nomark  as shipped but marker_rate:=0 (no linkage markers: what they cost a tick)
  bare         a plain rclpy timer publishing one JointState, on the SingleThreadedExecutor
               (the baseline)
  bare-2pub    the bare timer also publishing a TwistStamped (the node's two messages)
  bare-events  the bare timer on the EventsExecutor
  floor        the host's floor: the bare timer's message published from a plain thread that
               sleeps to each due time (no executor, rcl's rule for skipping late periods)
CPU is the publisher process's on-CPU time from the kernel (/proc/PID/task/*/schedstat,
nanoseconds, all threads) over the window. A measurement is kept only if the rest of the
machine was quiet meanwhile (other processes' CPU from /proc/stat below --quiet-limit cores);
a busy machine is retried, and with no quiet measurement the benchmark refuses to report
(exit 3) unless --allow-busy. Prints medians and spreads (min..max) over repeats of each
variant's CPU, missed ticks, and the CPU ratios of adjacent measurements: each variant / bare,
node / node-single, node-motor / node-cut; and each variant's top rate, two ways: the highest
rate whose median over repeats is <= 1 % missed (and every lower rate's), with its ratio to
bare's, and the spread of each repeat's own top (which one noisy measurement sinks). With the
floor among the variants, also the highest rate whose median of (variant's missed - floor's, in
the same repeat) is <= 1 %: what the publisher itself loses, not the host. For the top rate,
measure near it: --rates 2500 3000 3500 4000 4500 5000 --variants node bare floor.
--profile VARIANT runs that variant once more at the first CPU rate under cProfile and prints
where its Python time goes. Not a test: nothing
is asserted (targets: CPU at 1 kHz <= 1.2 x bare, max rate >= 0.9 x bare; motor drive
<= 1.3 x speed drive, no missed ticks where the speed drive has none).
"""

import argparse
from array import array
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
import time

from qrm_ros.core.common.names import (DIAGNOSTICS_TOPIC, JOINT_NAMES, JOINT_STATES_TOPIC,
                                       RAM_TWIST_TOPIC, STROKE_PAIR_STATUS)
from qrm_ros.node.process.ros_isolation import isolate_ros_traffic
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

RATES = [100.0, 1000.0, 2000.0, 3000.0, 5000.0]
CPU_RATES = (100.0, 1000.0)
VARIANTS = ('node', 'node-single', 'node-cut', 'node-motor', 'node-nomark', 'bare',
            'bare-2pub', 'bare-events', 'floor')
# (variant, baseline) CPU ratios printed besides each variant / bare.
RATIOS = (('node', 'node-single'), ('node-motor', 'node-cut'))
SUSTAINED_MISSED_FRACTION = 0.01
RETRIES = 3
EXIT_BUSY = 3


# Publishers (each run as `bench_node.py --publisher VARIANT RATE`) ------------------------

def _executor_kind(variant):
    """Return the executor a variant spins on: the shipped default, or the one named."""
    if variant.endswith('-single') or variant in ('bare', 'bare-2pub'):
        return 'single'
    return 'events'


def _node_parameters(variant, rate):
    from qrm_ros.core.dynamics.chain import Loads
    from rclpy.parameter import Parameter
    parameters = [Parameter('publish_rate', value=rate)]
    if variant in ('node-cut', 'node-motor'):
        loads = Loads.small_shaper()  # the main job's default cutting load
        parameters += [Parameter(name, value=float(getattr(loads, name)))
                       for name in Loads.field_names()]
    if variant == 'node-motor':
        parameters.append(Parameter('drive', value='motor'))
    if variant == 'node-nomark':
        parameters.append(Parameter('marker_rate', value=0.0))
    return parameters


def publisher_main(variant, rate, profile_path=None):
    import cProfile
    import rclpy
    from qrm_ros.node.process.ros_process import (init_rclpy, new_executor, spin_until_stopped,
                                                  StopRequest)
    init_rclpy()
    if variant.startswith('node'):
        from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode
        node = ShaperSimNode(parameter_overrides=_node_parameters(variant, rate))
    else:
        node, tick = _bare_node(rate, twist=variant == 'bare-2pub')
        if variant == 'floor':
            _start_sleeping_ticks(tick, rate)
        else:
            node.create_timer(1.0 / rate, tick)
    executor = new_executor(_executor_kind(variant))
    profile = cProfile.Profile() if profile_path else None
    try:
        executor.add_node(node)
        with StopRequest() as stop:
            if profile:
                profile.enable()  # the spinning only, not the start-up's imports
            spin_until_stopped(executor, stop)
        if profile:
            profile.disable()
            profile.dump_stats(profile_path)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def _bare_node(rate, twist):
    """Return a plain rclpy node and its tick, publishing a 5-joint JointState (and a twist)."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from sensor_msgs.msg import JointState

    node = rclpy.create_node('bare_publisher')
    publisher = node.create_publisher(JointState, JOINT_STATES_TOPIC, 10)
    twist_publisher = node.create_publisher(TwistStamped, RAM_TWIST_TOPIC, 10)
    message = JointState(name=list(JOINT_NAMES))
    twist_message = TwistStamped()
    clock = node.get_clock()

    def tick():
        now = clock.now()
        seconds = now.nanoseconds / NANOSECONDS_PER_SECOND
        message.header.stamp = now.to_msg()
        message.position = array('d', (seconds, seconds, seconds, seconds, seconds))
        message.velocity = array('d', (1.0, 1.0, 1.0, 1.0, 1.0))
        publisher.publish(message)
        if twist:
            twist_message.header.stamp = message.header.stamp
            twist_message.twist.linear.x = seconds
            twist_publisher.publish(twist_message)

    return node, tick


def _start_sleeping_ticks(tick, rate):
    """
    Call tick at each due time from a daemon thread that sleeps in between (one wake-up a tick).

    A tick a whole period late skips the periods passed, as rcl_timer_call does, so the
    misses counted are what any publisher on this machine would lose to late wake-ups.
    """
    import threading
    period = round(NANOSECONDS_PER_SECOND / rate)

    def run():
        due = time.monotonic_ns() + period
        while True:
            wait = due - time.monotonic_ns()
            if wait > 0:
                time.sleep(wait / NANOSECONDS_PER_SECOND)
            now = time.monotonic_ns()
            tick()
            due += period
            if due < now:
                due += ((now - due - 1) // period + 1) * period

    threading.Thread(target=run, daemon=True, name='floor_ticks').start()


# Measuring --------------------------------------------------------------------------------

def process_cpu_ns(pid):
    """On-CPU nanoseconds of every live thread of a process (kernel schedstat)."""
    total = 0
    for task in os.listdir(f'/proc/{pid}/task'):
        try:
            with open(f'/proc/{pid}/task/{task}/schedstat') as handle:
                total += int(handle.read().split()[0])
        except (FileNotFoundError, ProcessLookupError):
            pass  # a thread ended meanwhile
    return total


def machine_busy_ns():
    """CPU time spent by everything on the machine, in ns (/proc/stat, all cores)."""
    with open('/proc/stat') as handle:
        fields = [int(v) for v in handle.readline().split()[1:]]
    user, nice, system, idle, iowait, irq, softirq, steal = fields[:8]
    ticks = user + nice + system + irq + softirq + steal
    return ticks * NANOSECONDS_PER_SECOND / os.sysconf('SC_CLK_TCK')


class Probe:
    """
    Counts the stamps of the joint states it receives (reliable, deep queue).

    It also notes where the node's effort theory stands (its stroke-pair diagnostics): the
    node works it out once per setting in a worker process, a one-off that is not the
    steady cost of a tick, so a node is measured once that is done.
    """

    def __init__(self):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile
        from sensor_msgs.msg import JointState

        rclpy.init()
        self.node = rclpy.create_node('bench_probe')
        self.stamps = []
        self.theory_settled = False
        self.node.create_subscription(JointState, JOINT_STATES_TOPIC, self._on_joint_state,
                                      QoSProfile(depth=10000))
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics,
                                      QoSProfile(depth=100))
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def _on_joint_state(self, message):
        stamp = message.header.stamp
        self.stamps.append(stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec)

    def _on_diagnostics(self, message):
        for status in message.status:
            values = {item.key: item.value for item in status.values}
            # Worked out (its values there), or known to have none at this setting.
            if status.name == STROKE_PAIR_STATUS and values.get('effort_theory', '').startswith(
                    ('steady setting', 'unavailable', 'none: no steady')):
                self.theory_settled = True

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)


def measure(variant, rate, window, probe, quiet_limit, profile_path=None):
    """(missed and late fractions, CPU in % of a core, other load in cores, stamps received)."""
    command = [sys.executable, os.path.abspath(__file__), '--publisher', variant, str(rate)]
    command += [profile_path] if profile_path else []
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        probe.stamps.clear()
        deadline = time.monotonic() + 20.0
        while len(probe.stamps) < 10:
            probe.spin_for(0.01)
            if time.monotonic() > deadline:
                raise RuntimeError(f'no joint states from {variant}')
        probe.theory_settled = not variant.startswith('node')
        while not probe.theory_settled:  # past the effort theory's one-off work
            probe.spin_for(0.05)
            if time.monotonic() > deadline + 30.0:
                raise RuntimeError(f'{variant}: no stroke pair with its effort theory')
        probe.spin_for(0.2)  # past start-up
        probe.stamps.clear()
        own = os.getpid()
        cpu0, probe0, busy0 = process_cpu_ns(process.pid), process_cpu_ns(own), machine_busy_ns()
        wall0 = time.monotonic()
        probe.spin_for(window)
        wall = time.monotonic() - wall0
        cpu = process_cpu_ns(process.pid) - cpu0
        others = machine_busy_ns() - busy0 - cpu - (process_cpu_ns(own) - probe0)
        probe.spin_for(0.1)
        stamps = list(probe.stamps)
    finally:
        process.send_signal(2)
        try:
            process.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    missed, late = tick_misses(stamps, NANOSECONDS_PER_SECOND / rate)
    wall_ns = wall * NANOSECONDS_PER_SECOND
    return missed, late, 100.0 * cpu / wall_ns, others / wall_ns, len(stamps)


def tick_misses(stamps, period):
    """
    Return (missed, late) fractions of the ticks due between the first and last stamp.

    Missed: due but never published (rcl's timer skips a period only when its callback comes
    a whole period late). Late: published over half a period after the previous one's due
    time (the stamp is the clock when the callback ran), which the gap between two stamps
    rounds up to one more period.
    """
    if len(stamps) < 2:
        return 1.0, 0.0
    expected = round((stamps[-1] - stamps[0]) / period) + 1
    late = sum(max(0, round((b - a) / period) - 1) for a, b in zip(stamps, stamps[1:]))
    return max(0, expected - len(stamps)) / expected, late / expected


def quiet_measurement(variant, rate, window, probe, quiet_limit, allow_busy):
    for attempt in range(RETRIES):
        missed, late, cpu, others, received = measure(variant, rate, window, probe, quiet_limit)
        if received < 2:
            # Seen twice in about 500 windows, the publisher busy: what went missing is not
            # known, so the window is measured again rather than counted as all missed.
            print(f'    ({received} joint states reached the probe from {variant} at '
                  f'{rate:.0f} Hz; retry {attempt + 1}/{RETRIES})', flush=True)
            continue
        if others <= quiet_limit:
            return missed, late, cpu
        print(f'    (machine busy: other processes used {others:.2f} cores during '
              f'{variant} {rate:.0f} Hz; retry {attempt + 1}/{RETRIES})', flush=True)
    if allow_busy or received < 2:
        return missed, late, cpu  # the last try received none: counted as all missed
    return None


def spread(values):
    values = sorted(values)
    return f'median {statistics.median(values):6.2f} (min {values[0]:.2f}, max {values[-1]:.2f})'


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--repeat', type=int, default=5, help='interleaved repeats')
    parser.add_argument('--window', type=float, default=2.0, help='seconds per measurement')
    parser.add_argument('--variants', nargs='+', default=list(VARIANTS), choices=VARIANTS)
    parser.add_argument('--rates', nargs='+', type=float, default=RATES)
    parser.add_argument('--quiet-limit', type=float, default=0.2,
                        help='largest CPU use of other processes, in cores (default 0.2)')
    parser.add_argument('--allow-busy', action='store_true',
                        help='report even when the machine was busy (marked as such)')
    parser.add_argument('--profile', choices=VARIANTS,
                        help='run this variant once more under cProfile and print its profile')
    parser.add_argument('--publisher', nargs='+', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publisher:
        return publisher_main(args.publisher[0], float(args.publisher[1]),
                              *args.publisher[2:])
    isolate_ros_traffic(os.environ)
    probe = Probe()
    results = {}  # (variant, rate) -> list of (missed, cpu) per repeat
    for index in range(args.repeat):
        print(f'repeat {index + 1}/{args.repeat} ({os.cpu_count()} CPUs, window '
              f'{args.window} s)', flush=True)
        order = args.variants[index % len(args.variants):] + \
            args.variants[:index % len(args.variants)]
        for rate in args.rates:
            for variant in order:
                found = quiet_measurement(variant, rate, args.window, probe, args.quiet_limit,
                                          args.allow_busy)
                if found is None:
                    print(f'bench_node: the machine stayed busy (other processes above '
                          f'{args.quiet_limit} cores) through {RETRIES} tries of {variant} '
                          f'at {rate:.0f} Hz: no figures reported (--allow-busy reports '
                          'them anyway)', file=sys.stderr)
                    return EXIT_BUSY
                results.setdefault((variant, rate), []).append(found)
                print(f'  {variant:11s} {rate:6.0f} Hz: missed {100 * found[0]:5.2f} %, '
                      f'late {100 * found[1]:5.2f} %, CPU {found[2]:5.1f} %', flush=True)
    report(results, args)
    if args.profile:
        rate = next((r for r in CPU_RATES if r in args.rates), args.rates[0])
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, 'publisher.prof')
            _, _, cpu, others, _ = measure(args.profile, rate, args.window, probe,
                                           args.quiet_limit, path)
            print(f'\nprofile of {args.profile} at {rate:.0f} Hz (CPU {cpu:.1f} % under '
                  f'cProfile, other load {others:.2f} cores), Python time by function:')
            pstats.Stats(path).sort_stats('tottime').print_stats(15)
    return 0


def report(results, args):
    print(f'\nmedians over {args.repeat} interleaved repeats'
          + (' (busy machine allowed)' if args.allow_busy else ''))
    for rate in [r for r in CPU_RATES if r in args.rates]:
        for variant in args.variants:
            cpus = [cpu for _, _, cpu in results[variant, rate]]
            missed = [100 * missed for missed, _, _ in results[variant, rate]]
            late = [100 * late for _, late, _ in results[variant, rate]]
            print(f'CPU at {rate:6.0f} Hz, {variant:11s}: {spread(cpus)} % of a core; '
                  f'missed ticks {spread(missed)} %, late {spread(late)} %')
        pairs = [(variant, 'bare') for variant in args.variants if variant != 'bare']
        for variant, base in pairs + list(RATIOS):
            if variant not in args.variants or base not in args.variants:
                continue
            ratios = [cpu / base_cpu for (_, _, cpu), (_, _, base_cpu)
                      in zip(results[variant, rate], results[base, rate])]
            print(f'CPU at {rate:6.0f} Hz, {variant:11s} / {base:11s}: {spread(ratios)}')
    for column, what in enumerate(('missed', 'late')):
        # The highest rate whose median over repeats stays <= 1 % (and every lower one's):
        # one noisy measurement at a low rate does not sink it, as it does a repeat's top.
        tops = {variant: sustained_top(args.rates, lambda rate: statistics.median(
                    found[column] for found in results[variant, rate]))
                for variant in args.variants}
        for variant, top in tops.items():
            print(f'highest rate with a median <= 1 % {what} ticks, {variant:11s}: {top:6.0f} Hz'
                  + (f' ({top / tops["bare"]:.2f} x bare)' if tops.get('bare') else ''))
        for variant in args.variants:
            highest = [sustained_top(args.rates,
                                     lambda rate: results[variant, rate][index][column])
                       for index in range(args.repeat)]
            print(f'highest rate with <= 1 % {what} ticks, {variant:11s}: {spread(highest)} Hz')
    if 'floor' in args.variants:
        # What a publisher misses beyond what the host's late wake-ups cost any publisher in
        # the same repeat: near 1 %, the host's floor alone would decide the top above.
        tops = {variant: sustained_top(args.rates, lambda rate: statistics.median(
                    found[0] - floor[0] for found, floor
                    in zip(results[variant, rate], results['floor', rate])))
                for variant in args.variants if variant != 'floor'}
        for variant, top in tops.items():
            print(f'highest rate with a median <= 1 % missed above the floor, {variant:11s}: '
                  f'{top:6.0f} Hz' + (f' ({top / tops["bare"]:.2f} x bare)'
                                      if tops.get('bare') else ''))


def sustained_top(rates, fraction_at):
    """Return the highest rate with fraction_at(rate) <= 1 %, and every lower rate's (0: none)."""
    top = 0.0
    for rate in sorted(rates):
        if fraction_at(rate) > SUSTAINED_MISSED_FRACTION:
            break
        top = rate
    return top


if __name__ == '__main__':
    sys.exit(main())
