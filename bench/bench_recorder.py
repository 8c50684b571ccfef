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
Recorder benchmark: JointState + TwistStamped at 1 kHz each into mcap_recorder.

Publisher and recorder are separate processes. Prints messages offered vs recorded, the
recorder's CPU (from /proc), and write throughput against the raw mcap Writer writing the same
messages (bytes and timestamps from the recorded file) in the same run:

- write path: the recorder's own writing layer (McapRunFile: chunks closed per
  max_chunk_duration, fsync) vs mcap.Writer, messages per CPU second;
- end to end: messages per CPU second of the whole recorder process (DDS, rclpy, writing) vs
  mcap.Writer.

    python3 dev.py run python bench/bench_recorder.py [--seconds 5] [--runs 3]
"""

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from bench_node import cpu_seconds
from qrm_ros.ros_isolation import isolate_ros_traffic

RATE_HZ = 1000.0


def publish(seconds):
    """Child process: wait for the recorder, publish both topics at 1 kHz, report counts."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from sensor_msgs.msg import JointState
    rclpy.init()
    node = rclpy.create_node('bench_publisher')
    joints = node.create_publisher(JointState, 'joint_states', 1000)
    twist = node.create_publisher(TwistStamped, 'ram/twist', 1000)
    deadline = time.monotonic() + 20.0
    while (joints.get_subscription_count() < 1 or twist.get_subscription_count() < 1) and \
            time.monotonic() < deadline:
        time.sleep(0.01)
    joint_state = JointState()
    joint_state.header.frame_id = 'shaper_base'
    joint_state.name = ['input_shaft_joint', 'flywheel_joint', 'lever_joint', 'ram_joint',
                        'coupling_offset_joint']
    message = TwistStamped()
    sent = 0
    start = time.monotonic()
    print('started', flush=True)
    while True:
        due = start + sent / RATE_HZ
        now = time.monotonic()
        if due > start + seconds:
            break
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
    print(f'offered {sent} {sent}', flush=True)
    time.sleep(1.0)  # stay for reliable resends
    node.destroy_node()
    rclpy.shutdown()


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
    from mcap.writer import CompressionType
    from qrm_ros.recorder import McapRunFile
    start = time.process_time()
    run_file = McapRunFile(path, CompressionType.ZSTD, 1_000_000_000)
    channels = {}
    for topic, schema_name, log_time, publish_time, data in messages:
        if topic not in channels:
            channels[topic] = run_file.add_channel(topic, schema_name, [], '')
        run_file.add_message(channels[topic], log_time, publish_time, data)
    run_file.finish()
    return len(messages) / (time.process_time() - start)


def one_run(seconds, folder, env):
    from qrm_ros.bag_reader import open_run
    output = os.path.join(folder, f'bench_{time.time_ns()}.mcap')
    logs = open(os.path.join(folder, 'recorder.log'), 'w')
    recorder = subprocess.Popen(
        ['mcap_recorder', '--ros-args', '-p', f'output:={output}', '-p',
         'topics:=[joint_states, ram/twist]'], stdout=logs, stderr=logs, env=env)
    publisher = subprocess.Popen([sys.executable, __file__, '--publish', str(seconds)],
                                 stdout=subprocess.PIPE, text=True, env=env)
    assert publisher.stdout.readline().strip() == 'started'
    cpu_start, wall_start = cpu_seconds(recorder.pid), time.monotonic()
    offered = publisher.stdout.readline().split()
    cpu_used, wall = cpu_seconds(recorder.pid) - cpu_start, time.monotonic() - wall_start
    publisher.wait(30)
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(30) == 0, open(logs.name).read()
    run = open_run(output)
    messages = list(run.messages())
    counts = {t: 0 for t in ('/joint_states', '/ram/twist')}
    for message in messages:
        counts[message[0]] += 1
    raw = statistics.median(_write_raw(messages, output + f'.raw{i}') for i in range(3))
    ours = statistics.median(_write_recorder_path(messages, output + f'.ours{i}')
                             for i in range(3))
    recorded = counts['/joint_states'] + counts['/ram/twist']
    return {'offered': int(offered[1]) + int(offered[2]), 'recorded': recorded,
            'cpu': 100.0 * cpu_used / wall, 'write_ratio': ours / raw,
            'end_to_end_ratio': (recorded / cpu_used) / raw if cpu_used else float('nan'),
            'raw': raw, 'ours': ours, 'end_to_end': recorded / cpu_used if cpu_used else 0}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=5.0)
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--publish', type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish is not None:
        return publish(args.publish)
    env = dict(os.environ)
    isolate_ros_traffic(env)
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for index in range(args.runs):
            result = one_run(args.seconds, folder, env)
            results.append(result)
            print(f'run {index + 1}: offered {result["offered"]} recorded {result["recorded"]}, '
                  f'recorder CPU {result["cpu"]:.0f} %, write path {result["ours"]:.0f} msg/s '
                  f'vs raw mcap.Writer {result["raw"]:.0f} msg/s ({result["write_ratio"]:.2f}x), '
                  f'end to end {result["end_to_end"]:.0f} msg/CPU-s '
                  f'({result["end_to_end_ratio"]:.2f}x)', flush=True)

    def median(key):
        return statistics.median(r[key] for r in results)
    print(f'median of {len(results)} runs at 2 x {RATE_HZ:.0f} Hz for {args.seconds:g} s: '
          f'offered {median("offered"):.0f}, recorded {median("recorded"):.0f} '
          f'(lost {median("offered") - median("recorded"):.0f}); recorder CPU '
          f'{median("cpu"):.0f} % of one core')
    print(f'median write throughput vs raw mcap.Writer, same bytes, same run: write path '
          f'{median("write_ratio"):.2f}x, end to end (whole recorder process per CPU second) '
          f'{median("end_to_end_ratio"):.2f}x')
    return 0


if __name__ == '__main__':
    sys.exit(main())
