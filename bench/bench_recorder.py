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
default). Subscriber processes take both topics at the same time, with the same QoS
(reliable, depth 1000) and the same spin loop: mcap_recorder as shipped (rclpy's
EventsExecutor), bare rclpy nodes whose raw (serialized) subscriptions only count -- `floor`
on rclpy's SingleThreadedExecutor (the target's baseline) and `floor-events` on the
EventsExecutor -- and with --single-recorder also mcap_recorder on the SingleThreadedExecutor
(QRM_ROS_EXECUTOR=single, the previous default). All CPU times (user + system of the whole
process, all threads, from /proc) are taken over the same publishing window, so machine load
hits all alike; repeats rotate which starts first. Prints per repeat and then medians with
their spread (min..max): the CPU of each, the ratios recorder / floor (target <= 1.2),
recorder / floor-events and the single-threaded recorder / floor, messages lost by each
(target 0), and how busy the machine was.

Also the write path alone: the recorder's McapRunFile against the raw mcap Writer writing
the same recorded messages (messages per CPU second, same run). --profile runs the recorder
of one extra repeat under cProfile and prints where its Python time goes.

    python3 dev.py run python bench/bench_recorder.py [--seconds 10] [--repeats 5]
        [--single-recorder]
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
from qrm_ros.node.process.ros_isolation import isolate_ros_traffic

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


def floor(kind):
    """Child: bare raw subscriptions on the topics, same QoS and spin loop as the recorder."""
    from geometry_msgs.msg import TwistStamped
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from qrm_ros.node.process.ros_process import (init_rclpy, new_executor, spin_until_stopped,
                                                  StopRequest)
    init_rclpy()
    node = rclpy.create_node('bench_floor')
    count = [0]

    def take(data):
        count[0] += 1

    qos = QoSProfile(depth=FLOOR_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
    for topic, message_class in zip(TOPICS, (JointState, TwistStamped)):
        node.create_subscription(message_class, topic, take, qos, raw=True)
    executor = new_executor(kind)
    executor.add_node(node)
    with StopRequest() as stop:
        spin_until_stopped(executor, stop)
    executor.spin_once(timeout_sec=0.2)
    print(f'received {count[0]}', flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()


def recorder_command(output, profile_path=None):
    """Return the command that records TOPICS to output (profiled to profile_path if given)."""
    command = [sys.executable]
    if profile_path:
        command += ['-m', 'cProfile', '-o', profile_path]
    return command + ['-m', 'qrm_ros.cli.mcap_recorder', '--ros-args', '-p', f'output:={output}',
                      '-p', f'topics:=[{", ".join(TOPICS)}]', '-p', 'sim_wait_timeout:=60.0']


def one_repeat(index, seconds, rate, folder, env, roles, profile_path=None):
    """Run the publisher and the subscribers `roles` once; return their figures."""
    from qrm_ros.recording.bag_reader import open_run
    outputs, logs, processes = {}, {}, {}

    def start(role):
        if role.startswith('recorder'):
            outputs[role] = os.path.join(folder, f'bench_{index}_{role}_{time.time_ns()}.mcap')
            logs[role] = open(os.path.join(folder, f'{role}_{index}.log'), 'w')
            kind = 'single' if role == 'recorder-single' else 'events'
            return subprocess.Popen(
                recorder_command(outputs[role], profile_path if role == 'recorder' else None),
                stdout=logs[role], stderr=logs[role],
                env=dict(env, QRM_ROS_EXECUTOR=kind))
        kind = 'events' if role == 'floor-events' else 'single'
        return subprocess.Popen([sys.executable, __file__, '--floor', kind],
                                stdout=subprocess.PIPE, text=True, env=env)

    shift = index % len(roles)
    for role in roles[shift:] + roles[:shift]:
        processes[role] = start(role)
    publisher = subprocess.Popen([sys.executable, __file__, '--publish', str(seconds),
                                  str(rate), str(len(roles))], stdout=subprocess.PIPE,
                                 text=True, env=env)
    line = publisher.stdout.readline().strip()
    assert line == 'started', line
    start_cpu = {role: cpu_seconds(p.pid) for role, p in processes.items()}
    start_machine, start_wall = machine_cpu_seconds(), time.monotonic()
    offered = int(publisher.stdout.readline().split()[1])
    end_cpu = {role: cpu_seconds(p.pid) for role, p in processes.items()}
    end_machine, wall = machine_cpu_seconds(), time.monotonic() - start_wall
    publisher.wait(30)
    for process in processes.values():
        process.send_signal(signal.SIGINT)
    result = {'offered': offered, 'machine_busy': 100.0 * (end_machine[0] - start_machine[0])
              / (end_machine[1] - start_machine[1])}
    for role, process in processes.items():
        if role.startswith('recorder'):
            assert process.wait(60) == 0, open(logs[role].name).read()
            messages = list(open_run(outputs[role]).messages())
            result[role, 'received'] = len(messages)
            if role == 'recorder':
                result['messages'] = messages
        else:
            result[role, 'received'] = int(process.communicate(timeout=30)[0].split()[-1])
        result[role, 'cpu_seconds'] = end_cpu[role] - start_cpu[role]
        result[role, 'cpu'] = 100.0 * result[role, 'cpu_seconds'] / wall
    return result


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
    from qrm_ros.recording.mcap_run_file import COMPRESSIONS, McapRunFile
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


RATIOS = [('recorder', 'floor', ' (target <= 1.2)'), ('recorder', 'floor-events', ''),
          ('recorder-single', 'floor', ''), ('recorder', 'recorder-single', '')]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=10.0,
                        help='publishing window per repeat [s] (default 10)')
    parser.add_argument('--repeats', type=int, default=5, help='repeats (default 5)')
    parser.add_argument('--rate', type=float, default=DEFAULT_RATE,
                        help='publish rate per topic [Hz] (default 1000: 2 kHz aggregate)')
    parser.add_argument('--single-recorder', action='store_true',
                        help='also run mcap_recorder on the SingleThreadedExecutor')
    parser.add_argument('--profile', action='store_true',
                        help='one more repeat with the recorder under cProfile')
    parser.add_argument('--publish', nargs=3, type=float, help=argparse.SUPPRESS)
    parser.add_argument('--floor', choices=('single', 'events'), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish is not None:
        return publish(args.publish[0], args.publish[1], int(args.publish[2]))
    if args.floor:
        return floor(args.floor)
    env = dict(os.environ)
    isolate_ros_traffic(env)
    roles = ['recorder', 'floor', 'floor-events'] + (
        ['recorder-single'] if args.single_recorder else [])
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for index in range(args.repeats):
            result = one_repeat(index, args.seconds, args.rate, folder, env, roles)
            results.append(result)
            print(f'repeat {index + 1}: offered {result["offered"]}; '
                  + '; '.join(f'{role} received {result[role, "received"]}, CPU '
                              f'{result[role, "cpu"]:.1f} %' for role in roles)
                  + f'; machine busy {result["machine_busy"]:.0f} % of {os.cpu_count()} cores',
                  flush=True)
        messages = results[-1]['messages']
        raw = [_write_raw(messages, os.path.join(folder, f'raw{i}.mcap')) for i in range(3)]
        ours = [_write_recorder_path(messages, os.path.join(folder, f'ours{i}.mcap'))
                for i in range(3)]
        if args.profile:
            profile_path = os.path.join(folder, 'recorder.prof')
            one_repeat(args.repeats, args.seconds, args.rate, folder, env, ['recorder'],
                       profile_path)
            print('\nrecorder profile (one repeat, Python time by function, top 20):')
            pstats.Stats(profile_path).sort_stats('tottime').print_stats(20)

    print(f'\nmedian (min..max) of {len(results)} repeats, 2 x {args.rate:g} Hz for '
          f'{args.seconds:g} s each:')
    for role in roles:
        cpu = [r[role, 'cpu'] for r in results]
        lost = [r['offered'] - r[role, 'received'] for r in results]
        print(f'  {role:15s} CPU {_spread(cpu, 1)} % of one core; lost {_spread(lost, 0)} '
              '(target 0)')
    for role, base, note in RATIOS:
        if role in roles and base in roles:
            ratios = [r[role, 'cpu_seconds'] / r[base, 'cpu_seconds'] for r in results]
            print(f'  {role} / {base} CPU {_spread(ratios)}x{note}')
    print(f'  machine busy {_spread([r["machine_busy"] for r in results], 0)} % of '
          f'{os.cpu_count()} cores')
    print(f'  write path alone: McapRunFile {statistics.median(ours):.0f} msg/CPU-s vs raw '
          f'mcap.Writer {statistics.median(raw):.0f} msg/CPU-s '
          f'({statistics.median(ours) / statistics.median(raw):.2f}x, same messages)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
