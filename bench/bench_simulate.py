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
qrm_simulate's speed against its floor: the same messages serialized and written, nothing else.

The floor, per tick: fill a JointState (five joints' positions, velocities, efforts) and a
TwistStamped, serialize both with rclpy's serialize_message and write them with the mcap
Writer (zstd chunks), into a file. The simulator, per tick: the whole node tick (stepping,
efforts, stroke measurement and reports, the messages), serialization and writing, with the
node's default 100 Hz and offset +10 mm, for each drive. Ticks per second of the loop (the
set-up, about 0.1 s, apart), interleaved over repeats; medians and their spread; the ratio
simulator / floor (goal >= 0.7 for the speed drive) and how long an hour of machine time at
100 Hz takes.

    python3 dev.py run python bench/bench_simulate.py [--repeats 5] [--seconds 120]
"""

import argparse
from array import array
import os
import statistics
import tempfile
import time

from geometry_msgs.msg import TwistStamped
from mcap.writer import CompressionType, Writer
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from qrm_ros.core.names import JOINT_NAMES
from qrm_ros.node.offline_sim import Simulation
from qrm_ros.node.scenario import scenario_from_mapping

PERIOD_NS = 10_000_000


def floor(path, ticks):
    """Return the ticks per second of filling, serializing and writing the two messages."""
    with open(path, 'wb') as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start('ros2', 'bench')
        schema = writer.register_schema('sensor_msgs/msg/JointState', 'ros2msg', b'')
        joints = writer.register_channel('/joint_states', 'cdr', schema)
        twists = writer.register_channel('/ram/twist', 'cdr', schema)
        joint_state, twist = JointState(name=list(JOINT_NAMES)), TwistStamped()
        started = time.perf_counter()
        for tick in range(1, ticks + 1):
            stamp = tick * PERIOD_NS
            seconds, nanoseconds = divmod(stamp, 1_000_000_000)
            angle = tick * 0.0628
            joint_state.header.stamp.sec, joint_state.header.stamp.nanosec = seconds, nanoseconds
            joint_state.header.frame_id = 'shaper_base'
            joint_state.position = array('d', (angle, angle, 0.1, 0.05, 0.01))
            joint_state.velocity = array('d', (6.28, 5.1, 0.7, 0.3, 0.0))
            joint_state.effort = array('d', (1.5, 1.2, 3.4, 10.0, 35.0))
            writer.add_message(joints, stamp, serialize_message(joint_state), stamp)
            twist.header.stamp.sec, twist.header.stamp.nanosec = seconds, nanoseconds
            twist.header.frame_id = 'shaper_base'
            twist.twist.linear.x = 0.3
            writer.add_message(twists, stamp, serialize_message(twist), stamp)
        writer.finish()
        return ticks / (time.perf_counter() - started)


def simulated(path, seconds, drive):
    """Return the ticks per second of the simulator's loop on `seconds` of machine time."""
    scenario = scenario_from_mapping({'duration': seconds, 'parameters': {
        'coupling_offset': 0.01, 'drive': drive}})
    summary = Simulation(scenario, path).run()
    return summary.ticks / summary.loop_seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--seconds', type=float, default=120.0,
                        help='machine time per simulated run [s] (motor: a quarter)')
    args = parser.parse_args()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
    rates = {'floor': [], 'speed': [], 'motor': []}
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(args.repeats):
            for name in rates:
                path = os.path.join(folder, f'{name}_{repeat}.mcap')
                if name == 'floor':
                    rate = floor(path, round(args.seconds * 100))
                else:
                    rate = simulated(path, args.seconds / (4 if name == 'motor' else 1), name)
                rates[name].append(rate)
                os.unlink(path)
            print(f'repeat {repeat + 1}: ' + ', '.join(
                f'{name} {values[-1]:.0f} ticks/s' for name, values in rates.items()),
                flush=True)
    median = {name: statistics.median(values) for name, values in rates.items()}
    for name, values in rates.items():
        print(f'{name:6s} median {median[name]:8.0f} ticks/s ({min(values):.0f}..'
              f'{max(values):.0f}); an hour at 100 Hz in {360000 / median[name]:.1f} s')
    for drive in ('speed', 'motor'):
        ratios = [d / f for d, f in zip(rates[drive], rates['floor'])]
        print(f'{drive} drive / floor: median {statistics.median(ratios):.3f} '
              f'({min(ratios):.3f}..{max(ratios):.3f})')


if __name__ == '__main__':
    main()
