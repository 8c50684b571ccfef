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
Benchmark: the whole offline analysis against a bare rosbags read of the same messages.

Writes a synthetic one-hour, 100 Hz run (joint states and ram twist from the kinematics core,
through the recorder's own MCAP writer), then times, interleaved and several times each:
rosbags' AnyReader reading and deserializing the run's joint states (the baseline), and
``qrm_analyze``'s whole work (read, check, decode, segment, measure; no figures), both pinned
to one core, then both free to use every core. Prints each ratio analysis / baseline per
repeat, and their median and spread (target: <= 1.0x on one core and on all).

    python3 dev.py run python bench/bench_analysis.py [--hours 1] [--repeats 5]
"""

import argparse
import math
import os
from pathlib import Path
import statistics
import tempfile
import time

import numpy as np

from qrm_ros import analysis
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import JOINT_NAMES
from qrm_ros.node.recorder.recorder import COMPRESSIONS, McapRunFile

JOINTS = list(JOINT_NAMES)


def write_synthetic_run(path, seconds, rate=100.0, hold=None, twist=True):
    """
    Write a run with an offset schedule through the recorder's writer; return messages.

    hold: s at each offset, cycling through the schedule (None: the run split in seven);
    twist: write the ram twist beside the joint states.
    """
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    geometry = kin.Geometry.paper()
    schedule = np.array([-0.015, -0.01, -0.005, 0.0, 0.005, 0.01, 0.015])
    hold = seconds / schedule.size if hold is None else hold
    run_file = McapRunFile(str(path), COMPRESSIONS['zstd'], 1_000_000_000)  # the default
    joint_channel = run_file.add_channel('/joint_states', 'sensor_msgs/msg/JointState', [], '')
    twist_channel = (run_file.add_channel('/ram/twist', 'geometry_msgs/msg/TwistStamped', [], '')
                     if twist else None)
    run_file.add_metadata('qrm_ros.geometry', {k: repr(float(v)) for k, v in
                                               geometry.as_dict().items()})
    speed = 2 * math.pi
    start_ns = 1_800_000_000_000_000_000
    block = 36_000
    count = int(seconds * rate)
    for first in range(0, count, block):
        t = np.arange(first, min(first + block, count)) / rate
        offset = schedule[np.minimum((t // hold).astype(int), schedule.size - 1)
                          if hold * schedule.size >= seconds
                          else (t // hold).astype(int) % schedule.size]
        state = kin.state(geometry, offset, speed * t, speed)
        angle = np.mod(speed * t + math.pi, 2 * math.pi) - math.pi
        for i, seconds_in in enumerate(t):
            ns = start_ns + int(round(seconds_in * 1e9))
            header = types['std_msgs/msg/Header'](
                stamp=types['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
                frame_id='shaper_base')
            joints = types['sensor_msgs/msg/JointState'](
                header=header, name=JOINTS,
                position=np.array([angle[i], state.flywheel_angle[i], state.lever_angle[i],
                                   state.ram_position[i], offset[i]]),
                velocity=np.array([speed, state.flywheel_speed[i], state.lever_speed[i],
                                   state.ram_velocity[i], 0.0]),
                effort=np.zeros(0))
            vector = types['geometry_msgs/msg/Vector3']
            twist = types['geometry_msgs/msg/TwistStamped'](
                header=header, twist=types['geometry_msgs/msg/Twist'](
                    linear=vector(x=state.ram_velocity[i], y=0.0, z=0.0),
                    angular=vector(x=0.0, y=0.0, z=0.0)))
            run_file.add_message(joint_channel, ns + 200_000, ns, bytes(
                store.serialize_cdr(joints, 'sensor_msgs/msg/JointState')))
            if twist_channel is not None:
                run_file.add_message(twist_channel, ns + 210_000, ns, bytes(
                    store.serialize_cdr(twist, 'geometry_msgs/msg/TwistStamped')))
    run_file.finish()
    return (2 if twist_channel is not None else 1) * count


def analyse(path):
    result = analysis.analyse(analysis.read_recording(str(path)))
    return sum(row['stroke_pairs'] for row in result.rows)


def rosbags_read(path):
    from rosbags.highlevel import AnyReader
    count = 0
    with AnyReader([Path(path)]) as reader:
        connections = [c for c in reader.connections if c.topic == '/joint_states']
        for connection, _, raw in reader.messages(connections=connections):
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count


def _timed(function, path):
    start = time.perf_counter()
    result = function(path)
    return time.perf_counter() - start, result


def _summary(label, values, unit):
    values = sorted(values)
    return (f'{label}: median {statistics.median(values):.3f}{unit} (min {values[0]:.3f}, '
            f'max {values[-1]:.3f}, {len(values)} repeats)')


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--hours', type=float, default=1.0, help='run length [h]')
    parser.add_argument('--repeats', type=int, default=5, help='interleaved repeats per mode')
    args = parser.parse_args()
    every_core = os.sched_getaffinity(0)
    modes = {'one core': {min(every_core)}, f'all {len(every_core)} cores': every_core}
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, 'hour.mcap')
        start = time.perf_counter()
        messages = write_synthetic_run(path, args.hours * 3600.0)
        print(f'wrote {messages} messages ({os.path.getsize(path) / 1e6:.1f} MB) in '
              f'{time.perf_counter() - start:.1f} s through McapRunFile')
        times = {(mode, who): [] for mode in modes for who in ('ours', 'bare')}
        ratios = {mode: [] for mode in modes}
        for repeat in range(args.repeats):
            for mode, cores in modes.items():  # interleaved: drifts in load hit both alike
                os.sched_setaffinity(0, cores)  # worker processes inherit it
                order = ('bare', 'ours') if repeat % 2 else ('ours', 'bare')
                taken = {}
                for who in order:
                    taken[who], result = _timed(rosbags_read if who == 'bare' else analyse, path)
                    if who == 'ours':
                        pairs = result
                    else:
                        read = result
                    times[mode, who].append(taken[who])
                ratios[mode].append(taken['ours'] / taken['bare'])
                print(f'repeat {repeat + 1}, {mode}: analysis {taken["ours"]:.2f} s, bare read '
                      f'{taken["bare"]:.2f} s, ratio {ratios[mode][-1]:.2f}x', flush=True)
        os.sched_setaffinity(0, every_core)
        print(f'analysis: read + check + decode + segment + measure ({pairs} stroke pairs); '
              f'baseline: rosbags AnyReader reading and deserializing the same {read} joint '
              'states')
        for mode in modes:
            print(_summary(f'{mode}: analysis', times[mode, 'ours'], ' s'))
            print(_summary(f'{mode}: bare rosbags read', times[mode, 'bare'], ' s'))
            print(_summary(f'{mode}: ratio analysis / bare read', ratios[mode], 'x')
                  + ' (target <= 1.0x)')


if __name__ == '__main__':
    main()
