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
Recorder benchmark: mcap_recorder against the honest floor, a bare rclpy raw subscription.

A publisher process sends JointState and TwistStamped at --rate Hz each (2 kHz aggregate by
default). Two subscriber processes take both topics at the same time, with the same QoS
(reliable, depth 1000) and the same spin loop: mcap_recorder, and a bare rclpy node whose
raw (serialized) subscriptions only count. Both CPU times (user + system of the whole
process, all threads, from /proc) are taken over the same publishing window, so machine
load hits both alike; repeats alternate which of the two starts first. Prints per repeat
and then medians with their spread (min..max): the CPU of each, the ratio recorder / floor
(target <= 1.2), messages lost by each (target 0), and how busy the machine was.

Also the write path alone: the recorder's McapRunFile against the raw mcap Writer writing
the same recorded messages (messages per CPU second, same run). --profile runs the recorder
of one extra repeat under cProfile and prints where its Python time goes.

    python3 dev.py run python bench/bench_recorder.py [--seconds 10] [--repeats 5]
"""

import argparse
import cProfile  # noqa: F401  (the profiled recorder runs `python -m cProfile`)
import os
import pstats
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from process_stats import cpu_seconds, machine_cpu_seconds
from qrm_ros.ros_isolation import isolate_ros_traffic

HERE = os.path.dirname(os.path.abspath(__file__))
TOPICS = ('joint_states', 'ram/twist')
DEFAULT_RATE = 1000.0  # Hz per topic
FLOOR_DEPTH = 1000  # as the recorder's SUBSCRIPTION_DEPTH


def publish(seconds, rate, subscribers):
    """Child: wait for the subscribers, publish both topics at `rate`, report counts."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from sensor_msgs.msg import JointState
    rclpy.init()
    node = rclpy.create_node('bench_publisher')
    joints = node.create_publisher(JointState, 'joint_states', 1000)
    twist = node.create_publisher(TwistStamped, 'ram/twist', 1000)
    deadline = time.monotonic() + 30.0
    while (min(joints.get_subscription_count(), twist.get_subscription_count()) < subscribers
           and time.monotonic() < deadline):
        time.sleep(0.01)
    time.sleep(0.5)  # matched is not yet ready to receive at full rate everywhere
    joint_state = JointState()
    joint_state.header.frame_id = 'shaper_base'
    joint_state.name = ['input_shaft_joint', 'flywheel_joint', 'lever_joint', 'ram_joint',
                        'coupling_offset_joint']
    message = TwistStamped()
    sent = 0
    start = time.monotonic()
    print('started', flush=True)
    while True:
        due = start + sent / rate
        if due > start + seconds:
            break
        now = time.monotonic()
        if due > now:
            time.sleep(due - now)
        stamp = node.get_clock().now().to_msg()
        joint_state.header.stamp = stamp
        joint_state.position = [sent * 1e-3 + k for k in range(5)]
        joint_state.velocity = [sent * -1e-3 + k for k in range(5)]
        joints.publish(joint_state)
        message.header.stamp = stamp
        message.twist.linear.x = sent * 1e-4
        twist.publish(message)
        sent += 1
    print(f'offered {2 * sent}', flush=True)
    time.sleep(1.0)  # stay for reliable resends
    node.destroy_node()
    rclpy.shutdown()


def floor():
    """Child: bare raw subscriptions on the topics, same QoS and spin loop as the recorder."""
    from geometry_msgs.msg import TwistStamped
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from qrm_ros.ros_process import init_rclpy, spin_until_stopped, StopRequest
    init_rclpy()
    node = rclpy.create_node('bench_floor')
    count = [0]

    def take(data):
        count[0] += 1

    qos = QoSProfile(depth=FLOOR_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
    for topic, message_class in zip(TOPICS, (JointState, TwistStamped)):
        node.create_subscription(message_class, topic, take, qos, raw=True)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    with StopRequest() as stop:
        spin_until_stopped(executor, stop)
    executor.spin_once(timeout_sec=0.2)
    print(f'received {count[0]}', flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def _recorder_command(output, profile_path=None):
    command = [sys.executable]
    if profile_path:
        command += ['-m', 'cProfile', '-o', profile_path]
    return command + ['-m', 'qrm_ros.recorder', '--ros-args', '-p', f'output:={output}',
                      '-p', f'topics:=[{", ".join(TOPICS)}]', '-p', 'sim_wait_timeout:=60.0']


def one_repeat(index, seconds, rate, folder, env, profile_path=None):
    from qrm_ros.bag_reader import open_run
    output = os.path.join(folder, f'bench_{index}_{time.time_ns()}.mcap')
    log = open(os.path.join(folder, f'recorder_{index}.log'), 'w')
    starters = [
        lambda: subprocess.Popen(_recorder_command(output, profile_path), stdout=log,
                                 stderr=log, env=env),
        lambda: subprocess.Popen([sys.executable, __file__, '--floor'],
                                 stdout=subprocess.PIPE, text=True, env=env),
    ]
    if index % 2:
        recorder, bare = starters[0](), starters[1]()
    else:
        bare, recorder = starters[1](), starters[0]()
    publisher = subprocess.Popen([sys.executable, __file__, '--publish', str(seconds),
                                  str(rate)], stdout=subprocess.PIPE, text=True, env=env)
    line = publisher.stdout.readline().strip()
    assert line == 'started', line
    start = (cpu_seconds(recorder.pid), cpu_seconds(bare.pid), machine_cpu_seconds(),
             time.monotonic())
    offered = int(publisher.stdout.readline().split()[1])
    end = (cpu_seconds(recorder.pid), cpu_seconds(bare.pid), machine_cpu_seconds(),
           time.monotonic())
    publisher.wait(30)
    for process in (recorder, bare):
        process.send_signal(signal.SIGINT)
    assert recorder.wait(60) == 0, open(log.name).read()
    received = int(bare.communicate(timeout=30)[0].split()[-1])
    wall = end[3] - start[3]
    machine_busy = (end[2][0] - start[2][0]) / (end[2][1] - start[2][1])
    messages = list(open_run(output).messages())
    return {'offered': offered, 'recorded': len(messages), 'floor_received': received,
            'recorder_cpu': 100.0 * (end[0] - start[0]) / wall,
            'floor_cpu': 100.0 * (end[1] - start[1]) / wall,
            'ratio': (end[0] - start[0]) / (end[1] - start[1]),
            'machine_busy': 100.0 * machine_busy, 'messages': messages, 'output': output}


def _write_raw(messages, path):
    from mcap.writer import CompressionType, Writer
    start = time.process_time()
    with open(path, 'wb') as handle:
        writer = Writer(handle, compression=CompressionType.ZSTD)
        writer.start('ros2', 'bench')
        channels = {}
        for topic, schema_name, log_time, publish_time, data in messages:
            if topic not in channels:
                schema = writer.register_schema(schema_name, 'ros2msg', b'')
                channels[topic] = writer.register_channel(topic, 'cdr', schema)
            writer.add_message(channels[topic], log_time, data, publish_time)
        writer.finish()
    return len(messages) / (time.process_time() - start)


def _write_recorder_path(messages, path):
    from qrm_ros.mcap_run_file import COMPRESSIONS, McapRunFile
    start = time.process_time()
    run_file = McapRunFile(path, COMPRESSIONS['zstd'], 1_000_000_000)
    channels = {}
    for topic, schema_name, log_time, publish_time, data in messages:
        if topic not in channels:
            channels[topic] = run_file.add_channel(topic, schema_name, [], '')
        run_file.add_message(channels[topic], log_time, publish_time, data)
    run_file.finish()
    return len(messages) / (time.process_time() - start)


def _spread(values, digits=2):
    return (f'{statistics.median(values):.{digits}f} '
            f'({min(values):.{digits}f}..{max(values):.{digits}f})')


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=10.0,
                        help='publishing window per repeat [s] (default 10)')
    parser.add_argument('--repeats', type=int, default=5, help='repeats (default 5)')
    parser.add_argument('--rate', type=float, default=DEFAULT_RATE,
                        help='publish rate per topic [Hz] (default 1000: 2 kHz aggregate)')
    parser.add_argument('--profile', action='store_true',
                        help='one more repeat with the recorder under cProfile')
    parser.add_argument('--publish', nargs=2, type=float, help=argparse.SUPPRESS)
    parser.add_argument('--floor', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish is not None:
        return publish(args.publish[0], args.publish[1], 2)
    if args.floor:
        return floor()
    env = dict(os.environ)
    isolate_ros_traffic(env)
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for index in range(args.repeats):
            result = one_repeat(index, args.seconds, args.rate, folder, env)
            results.append(result)
            print(f'repeat {index + 1}: offered {result["offered"]}, recorded '
                  f'{result["recorded"]}, floor received {result["floor_received"]}; CPU '
                  f'recorder {result["recorder_cpu"]:.1f} %, floor {result["floor_cpu"]:.1f} % '
                  f'-> {result["ratio"]:.2f}x; machine busy {result["machine_busy"]:.0f} % of '
                  f'{os.cpu_count()} cores', flush=True)
        messages = results[-1]['messages']
        raw = [_write_raw(messages, os.path.join(folder, f'raw{i}.mcap')) for i in range(3)]
        ours = [_write_recorder_path(messages, os.path.join(folder, f'ours{i}.mcap'))
                for i in range(3)]
        if args.profile:
            profile_path = os.path.join(folder, 'recorder.prof')
            one_repeat(args.repeats, args.seconds, args.rate, folder, env, profile_path)
            print('\nrecorder profile (one repeat, Python time by function, top 20):')
            pstats.Stats(profile_path).sort_stats('tottime').print_stats(20)

    def values(key):
        return [r[key] for r in results]
    lost = [r['offered'] - r['recorded'] for r in results]
    floor_lost = [r['offered'] - r['floor_received'] for r in results]
    print(f'\nmedian (min..max) of {len(results)} repeats, 2 x {args.rate:g} Hz for '
          f'{args.seconds:g} s each:')
    print(f'  recorder CPU {_spread(values("recorder_cpu"), 1)} % of one core, bare raw '
          f'subscription {_spread(values("floor_cpu"), 1)} %')
    print(f'  recorder / floor CPU {_spread(values("ratio"))}x (target <= 1.2)')
    print(f'  lost: recorder {_spread(lost, 0)}, floor {_spread(floor_lost, 0)} (target 0)')
    print(f'  machine busy {_spread(values("machine_busy"), 0)} % of {os.cpu_count()} cores')
    print(f'  write path alone: McapRunFile {statistics.median(ours):.0f} msg/CPU-s vs raw '
          f'mcap.Writer {statistics.median(raw):.0f} msg/CPU-s '
          f'({statistics.median(ours) / statistics.median(raw):.2f}x, same messages)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
