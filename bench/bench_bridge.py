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
Bridge benchmark: qrm_bridge serving a 1 kHz shaper_sim to one Foxglove client.

Part 1, CPU and latency (--repeats): shaper_sim publishes joint states at --rate Hz and its
linkage markers (30 Hz); qrm_bridge serves both topics to Foxglove's own protocol client
(Node.js, counting and timing what it decodes). Its baselines in the same run, over the same
window: two bare rclpy processes whose raw subscriptions of the same topics, with the same
QoS, only count, one on the bridge's executor (the EventsExecutor), one on rclpy's
SingleThreadedExecutor. Prints the CPU of each (user + system of the whole process, from
/proc), the ratios bridge / bare (goal <= 1.5), the messages each got, and the
delivery latency of the joint states from their stamp to the client (median, 99th percentile),
beside a DDS subscriber's in the same run; and what the bridge costs per message over the bare
subscription beside what the SDK's server alone costs per message (a plain loop logging to a
channel one client subscribes to).

Part 2, a stalled client (--stall-seconds): beside the joint states, a stand-in publisher sends
--big-size-byte images at --big-rate Hz. One client reads everything; another subscribes and
then stops reading. Prints whether the reading client got every message DDS delivered while
the other stalled, the bridge's memory before, during and after (bounded: at most about
--client-queue images per client, not what the stalled client was sent), how many messages
the stalled client lost (counted at the client when it reads again), and the bridge's notices.

    python3 dev.py run python bench/bench_bridge.py [--seconds 10] [--repeats 3]
        [--stall-seconds 20]
"""

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from process_stats import cpu_seconds, machine_cpu_seconds, rss_bytes
from qrm_ros.node.bridge.foxglove_bridge import DEFAULT_CLIENT_QUEUE
from qrm_ros.node.process.ros_isolation import isolate_ros_traffic

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), 'test'))
from foxglove_client import (bridge_address, FoxgloveClient, node_executable,  # noqa: E402
                             node_modules)

TOPICS = ('/joint_states', '/linkage_markers')
FLOORS = ('events', 'single')  # the bare subscriptions' executors
IMAGE_TOPIC = '/bench_image'
SETTLE_TIMEOUT = 60.0  # s, for processes to start and messages to flow


# --- children ------------------------------------------------------------------------------

def floor(kind):
    """Child: bare raw subscriptions of TOPICS that only count (the bridge's QoS), on `kind`."""
    import rclpy
    from qrm_ros.node.recorder.recorder import adapted_request_qos
    from qrm_ros.node.process.ros_process import (init_rclpy, new_executor, spin_until_stopped,
                                                  StopRequest)
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray
    init_rclpy()
    node = rclpy.create_node(f'bench_floor_{kind}')
    count = [0]

    def take(data):
        count[0] += 1
    signal.signal(signal.SIGUSR1, lambda *_: print(f'received {count[0]}', flush=True))
    for topic, message_type in zip(TOPICS, (JointState, MarkerArray)):
        while not node.get_publishers_info_by_topic(topic):
            time.sleep(0.05)
        qos, _ = adapted_request_qos([i.qos_profile for i in
                                      node.get_publishers_info_by_topic(topic)])
        node.create_subscription(message_type, topic, take, qos, raw=True)
    print('subscribed', flush=True)
    executor = new_executor(kind)
    executor.add_node(node)
    with StopRequest() as stop:
        spin_until_stopped(executor, stop)
    print(f'received {count[0]}', flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()


def probe(topics):
    """Child: a DDS subscriber keeping each stamped message's stamp and latency (ms)."""
    import json
    import rclpy
    from qrm_ros.node.process.ros_process import (init_rclpy, new_executor, spin_until_stopped,
                                                  StopRequest)
    from sensor_msgs.msg import Image, JointState
    init_rclpy()
    node = rclpy.create_node('bench_probe')
    seen = {}

    def taker(topic):
        def take(message):
            now = time.time_ns()
            stamp = message.header.stamp
            seen.setdefault(topic, []).append(
                (f'{stamp.sec}.{stamp.nanosec:09d}',
                 (now - stamp.sec * 1_000_000_000 - stamp.nanosec) / 1e6))
        return take
    for topic in topics:
        node.create_subscription(Image if topic == IMAGE_TOPIC else JointState, topic,
                                 taker(topic), 1000)
    executor = new_executor('events')
    executor.add_node(node)
    with StopRequest() as stop:
        spin_until_stopped(executor, stop)
    print(json.dumps(seen), flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()


def images(size, rate):
    """Child: publish stamped images of `size` bytes at `rate` Hz until stopped."""
    import rclpy
    from qrm_ros.node.process.ros_process import init_rclpy, StopRequest
    from sensor_msgs.msg import Image
    init_rclpy()
    node = rclpy.create_node('bench_images')
    publisher = node.create_publisher(Image, IMAGE_TOPIC, 10)
    message = Image(height=1, width=size, encoding='mono8', step=size, data=bytes(size))
    sent, start = 0, time.monotonic()
    with StopRequest() as stop:
        while not stop:
            due = start + sent / rate
            time.sleep(max(0.0, due - time.monotonic()))
            message.header.stamp = node.get_clock().now().to_msg()
            publisher.publish(message)
            sent += 1
    node.destroy_node()
    rclpy.try_shutdown()


def sdk_alone(rate, seconds):
    """Child: the SDK's server alone, fed 300-byte messages at `rate` for one subscribed client."""
    import resource
    import foxglove
    from foxglove import Channel, Context, Schema

    def cpu():
        usage = resource.getrusage(resource.RUSAGE_SELF)
        return usage.ru_utime + usage.ru_stime

    def paced(send):
        start, count = time.monotonic(), int(rate * seconds)
        before = cpu()
        for index in range(count):
            time.sleep(max(0.0, start + index / rate - time.monotonic()))
            send()
        return (cpu() - before) / count
    context = Context()
    server = foxglove.start_server(port=0, context=context)
    channel = Channel('/sdk_alone', schema=Schema(name='std_msgs/msg/String', encoding='ros2msg',
                                                  data=b'string data\n'),
                      message_encoding='cdr', context=context)
    print(f'ws://127.0.0.1:{server.port}', flush=True)
    while not channel.has_sinks():
        time.sleep(0.01)
    data = b'\x00\x01\x00\x00' + (292).to_bytes(4, 'little') + b'a' * 291 + b'\x00'
    log = channel.base.log
    with_sdk = paced(lambda: log(data))
    loop = paced(lambda: None)
    print(f'{(with_sdk - loop) * 1e6:.1f}', flush=True)
    server.stop()


# --- the parent ----------------------------------------------------------------------------

class Run:
    """The processes of one measurement, stopped together."""

    def __init__(self, env, folder):
        self.env, self.folder, self.processes, self.clients = env, folder, {}, []

    def start(self, name, command, **kwargs):
        log = open(os.path.join(self.folder, f'{name}.log'), 'w')
        process = subprocess.Popen(command, env=self.env, stdout=kwargs.pop('stdout', log),
                                   stderr=log, text=True, **kwargs)
        self.processes[name] = process
        return process

    def bridge(self, *arguments):
        process = self.start('bridge', [sys.executable, '-m', 'qrm_ros.cli.qrm_bridge',
                                        '--port', '0', *arguments], stdout=subprocess.PIPE)
        self.bridge_output = []
        return process, bridge_address(process, self.bridge_output, SETTLE_TIMEOUT)

    def client(self, address, modules, topics):
        client = FoxgloveClient(address, modules)
        self.clients.append(client)
        for topic in topics:
            client.send(op='quiet', topic=topic)
            client.send(op='subscribe', topic=topic)
        return client

    def stop(self):
        for client in self.clients:
            client.close()
        for process in reversed(list(self.processes.values())):
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        outputs = {}
        for name, process in self.processes.items():
            try:
                outputs[name] = process.communicate(timeout=30)[0]
            except subprocess.TimeoutExpired:
                process.kill()
                outputs[name] = process.communicate()[0]
        return outputs


def bare_count(process):
    """Ask the bare subscriber how many messages it has taken so far."""
    process.send_signal(signal.SIGUSR1)
    return int(process.stdout.readline().split()[-1])


def send_period(args):
    return [] if args.send_period is None else ['--send-period', repr(args.send_period)]


def report(client, timeout=60.0):
    client.events.clear()
    client.send(op='report')
    return client.wait_event('report', timeout=timeout)


def caught_up(client, topics, live_ms=500.0, timeout=120.0):
    """Report once the client reads live again: its last message of each topic is fresh."""
    deadline = time.monotonic() + timeout
    while True:
        now = report(client, timeout=timeout)
        if all(now['latencies'].get(t) and now['latencies'][t][-1] < live_ms for t in topics):
            return now
        assert time.monotonic() < deadline, 'the stalled client never caught up'
        time.sleep(0.5)


def counted(client, topics):
    """Wait until the client has messages of every topic."""
    def enough(events):
        client.send(op='count')
        counts = next((e['counts'] for e in reversed(events) if e['event'] == 'count'), {})
        return all(counts.get(t, 0) > 0 for t in topics)
    client.wait(enough, SETTLE_TIMEOUT, f'messages of {topics}')


def percentile(values, fraction):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


def cpu_repeat(args, env, modules, folder):
    """One window: bridge and bare subscriber CPU; latencies through the bridge and DDS."""
    import json
    run = Run(env, folder)
    try:
        run.start('sim', [sys.executable, '-m', 'qrm_ros.cli.shaper_sim', '--ros-args', '-p',
                          f'publish_rate:={float(args.rate)}'])
        bridge, address = run.bridge('--topics', *TOPICS, *send_period(args))
        bares = {kind: run.start(f'floor_{kind}', [sys.executable, __file__, '--floor', kind],
                                 stdout=subprocess.PIPE) for kind in FLOORS}
        for bare in bares.values():
            assert bare.stdout.readline().strip() == 'subscribed'
        run.start('probe', [sys.executable, __file__, '--probe', TOPICS[0]],
                  stdout=subprocess.PIPE)
        viewer = run.client(address, modules, TOPICS)
        counted(viewer, TOPICS)
        before = report(viewer)['counts']
        counts_bare = [bare_count(bares['events'])]
        measured = (('bridge', bridge), *bares.items())
        start_cpu = {name: cpu_seconds(p.pid) for name, p in measured}
        start_machine, start_wall = machine_cpu_seconds(), time.monotonic()
        time.sleep(args.seconds)
        end_cpu = {name: cpu_seconds(p.pid) for name, p in measured}
        end_machine, wall = machine_cpu_seconds(), time.monotonic() - start_wall
        after = report(viewer)
        counts_bare.append(bare_count(bares['events']))
    finally:
        outputs = run.stop()
    received_bare = counts_bare[1] - counts_bare[0]
    dds_seen = json.loads(outputs['probe'].strip().splitlines()[-1])
    latency_client = after['latencies'][TOPICS[0]]
    latency_dds = [latency for _, latency in dds_seen[TOPICS[0]]]
    return {
        'bridge': 100.0 * (end_cpu['bridge'] - start_cpu['bridge']) / wall,
        **{kind: 100.0 * (end_cpu[kind] - start_cpu[kind]) / wall for kind in FLOORS},
        'client_messages': sum(after['counts'].values()) - sum(before.values()),
        'bare_messages': received_bare,
        'latency_client': (statistics.median(latency_client),
                           percentile(latency_client, 0.99)),
        'latency_dds': (statistics.median(latency_dds), percentile(latency_dds, 0.99)),
        'machine_busy': 100.0 * (end_machine[0] - start_machine[0])
        / (end_machine[1] - start_machine[1]),
    }


def stall(args, env, modules, folder):
    """Stall one client for a while; return the other's messages and the bridge's memory."""
    import json
    run = Run(env, folder)
    topics = (TOPICS[0], IMAGE_TOPIC)
    try:
        run.start('sim', [sys.executable, '-m', 'qrm_ros.cli.shaper_sim', '--ros-args', '-p',
                          f'publish_rate:={float(args.rate)}'])
        run.start('images', [sys.executable, __file__, '--images', str(args.big_size),
                             str(args.big_rate)])
        bridge, address = run.bridge('--topics', *topics, '--client-queue',
                                     str(args.client_queue), *send_period(args))
        run.start('probe', [sys.executable, __file__, '--probe', *topics],
                  stdout=subprocess.PIPE)
        reader = run.client(address, modules, topics)
        stalled = run.client(address, modules, topics)
        counted(reader, topics)
        counted(stalled, topics)
        rss_before = rss_bytes(bridge.pid)
        stalled.send(op='stall', seconds=args.stall_seconds)
        samples, end = [], time.monotonic() + args.stall_seconds
        while time.monotonic() < end:
            samples.append(rss_bytes(bridge.pid))
            time.sleep(0.5)
        late = caught_up(stalled, topics)
        good = report(reader)
        rss_after = rss_bytes(bridge.pid)
    finally:
        outputs = run.stop()
    dds_seen = json.loads(outputs['probe'].strip().splitlines()[-1])
    result = {'rss': (rss_before, max(samples), rss_after)}
    for topic in topics:
        delivered = [stamp for stamp, _ in dds_seen[topic]]
        got = set(good['stamps'][topic])
        first, last = min(got, key=float), max(got, key=float)
        window = [s for s in delivered if float(first) <= float(s) <= float(last)]
        result[topic] = {'dds': len(window), 'missing_at_reader': len(set(window) - got),
                         'stalled_got': len(set(late['stamps'].get(topic, [])) & set(window))}
    with open(os.path.join(folder, 'bridge.log')) as log:
        result['notices'] = sum('falls behind' in line for line in log)
    return result


def run_sdk_alone(args, env, modules, folder):
    """Return the SDK's own CPU per message (us) serving one client, measured in a child."""
    run = Run(env, folder)
    try:
        child = run.start('sdk', [sys.executable, __file__, '--sdk-alone', str(args.rate),
                                  str(args.seconds)], stdout=subprocess.PIPE)
        address = child.stdout.readline().strip()
        viewer = run.client(address, modules, ['/sdk_alone'])
        viewer.wait_event('subscribed', topic='/sdk_alone')
        return float(child.stdout.readline())
    finally:
        run.stop()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--rate', type=float, default=1000.0, help='joint states, Hz')
    parser.add_argument('--stall-seconds', type=float, default=20.0)
    parser.add_argument('--big-size', type=int, default=65536, help='image bytes')
    parser.add_argument('--big-rate', type=float, default=100.0, help='images, Hz')
    parser.add_argument('--client-queue', type=int, default=DEFAULT_CLIENT_QUEUE)
    parser.add_argument('--send-period', type=float, default=None,
                        help='the bridge\'s --send-period (default: its own)')
    parser.add_argument('--floor', choices=FLOORS, help=argparse.SUPPRESS)
    parser.add_argument('--probe', nargs='+', help=argparse.SUPPRESS)
    parser.add_argument('--images', nargs=2, type=float, help=argparse.SUPPRESS)
    parser.add_argument('--sdk-alone', nargs=2, type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.floor:
        return floor(args.floor)
    if args.probe:
        return probe(args.probe)
    if args.images:
        return images(int(args.images[0]), args.images[1])
    if args.sdk_alone:
        return sdk_alone(*args.sdk_alone)
    if node_executable() is None:
        sys.exit('bench_bridge: Node.js is needed (Foxglove\'s client runs on it)')
    env = dict(os.environ)
    isolate_ros_traffic(env)
    modules = node_modules()
    with tempfile.TemporaryDirectory() as folder:
        results = []
        for index in range(args.repeats):
            result = cpu_repeat(args, env, modules, folder)
            results.append(result)
            print(f'repeat {index + 1}: bridge {result["bridge"]:.1f} % CPU, bare '
                  f'{result["events"]:.1f} % (events) / {result["single"]:.1f} % (single), '
                  f'ratios {result["bridge"] / result["events"]:.2f} / '
                  f'{result["bridge"] / result["single"]:.2f}; '
                  f'client got {result["client_messages"]} messages, bare '
                  f'{result["bare_messages"]}; latency through the bridge median '
                  f'{result["latency_client"][0]:.2f} ms, p99 {result["latency_client"][1]:.2f}'
                  f' ms (DDS alone {result["latency_dds"][0]:.2f} / '
                  f'{result["latency_dds"][1]:.2f} ms); machine {result["machine_busy"]:.0f} %'
                  ' busy', flush=True)
        print()
        for kind in FLOORS:
            ratios = [r['bridge'] / r[kind] for r in results]
            print(f'CPU bridge / bare raw subscription on the {kind} executor, median of '
                  f'{len(ratios)}: {statistics.median(ratios):.2f} ({min(ratios):.2f}..'
                  f'{max(ratios):.2f}); goal <= 1.5')
        busy = [r['machine_busy'] for r in results]
        print(f'machine {min(busy):.0f}-{max(busy):.0f} % busy')
        for key, name in (('latency_client', 'through the bridge'), ('latency_dds', 'DDS')):
            print(f'latency {name}: median {statistics.median(r[key][0] for r in results):.2f}'
                  f' ms, p99 {statistics.median(r[key][1] for r in results):.2f} ms')
        sdk = run_sdk_alone(args, env, modules, folder)
        per_message = [(r['bridge'] - r['events']) / 100.0 * args.seconds / r['client_messages']
                       * 1e6 for r in results]
        print(f'the bridge over the bare subscription: {statistics.median(per_message):.0f} us '
              f'of CPU per message; the SDK alone, from a plain loop: {sdk:.0f} us per message')
        stalled = stall(args, env, modules, folder)
    mib = [value / 2**20 for value in stalled['rss']]
    sent = args.big_size * args.big_rate * args.stall_seconds / 2**20
    print(f'\nstalled client for {args.stall_seconds:g} s (queue {args.client_queue} messages, '
          f'{args.big_size} B images at {args.big_rate:g} Hz = {sent:.0f} MiB sent its way):')
    print(f'  bridge RSS {mib[0]:.1f} MiB before, at most {mib[1]:.1f} MiB while stalled, '
          f'{mib[2]:.1f} MiB after')
    for topic in (TOPICS[0], IMAGE_TOPIC):
        figures = stalled[topic]
        print(f'  {topic}: DDS delivered {figures["dds"]}, the reading client missed '
              f'{figures["missing_at_reader"]}; the stalled client got {figures["stalled_got"]}'
              f' (lost {figures["dds"] - figures["stalled_got"]})')
    print(f'  the bridge reported the slow client {stalled["notices"]} time(s)')


if __name__ == '__main__':
    main()
