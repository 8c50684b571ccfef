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
Benchmark: the cost of one linkage MarkerArray against one joint-state tick, in this run.

The baseline is what the node does every tick for joint_states: the core's state and a
JointState filled and serialized. Measured: linkage_marker_array with the node's state
passed in (what the node will do), without it, and with the offset moving (no cached
ratios), each plus serialization (what publish adds). Prints the median and the spread
(min-max of the repeat medians) in microseconds, and ratios to the baseline.

    python3 dev.py run python bench/bench_markers.py [--calls 2000] [--repeats 7]
"""

import argparse
import math
import statistics
import time

from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from qrm_ros.core import kinematics as kin
from qrm_ros.node.shaper_sim.linkage_markers import linkage_marker_array
from qrm_ros.core.common.names import JOINT_NAMES


def per_call_microseconds(function, calls, repeats):
    medians = []
    for _ in range(repeats):
        start = time.perf_counter()
        for index in range(calls):
            function(index)
        medians.append((time.perf_counter() - start) / calls * 1e6)
    return statistics.median(medians), min(medians), max(medians)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--calls', type=int, default=2000)
    parser.add_argument('--repeats', type=int, default=7)
    args = parser.parse_args()
    geometry = kin.Geometry.paper()
    joint_state = JointState(name=list(JOINT_NAMES))

    def angle(index):
        return 0.01 * index

    def joint_state_tick(index):
        state = kin.state(geometry, 0.01, angle(index), 2 * math.pi)
        joint_state.header.stamp.nanosec = index
        joint_state.position = [angle(index), state.flywheel_angle, state.lever_angle,
                                state.ram_position, 0.01]
        joint_state.velocity = [2 * math.pi, state.flywheel_speed, state.lever_speed,
                                state.ram_velocity, 0.0]
        serialize_message(joint_state)

    def markers_with_state(index):
        state = kin.state(geometry, 0.01, angle(index), 2 * math.pi)
        serialize_message(linkage_marker_array(geometry, 0.01, angle(index), index,
                                               'shaper_base', mechanism_state=state))

    def markers_alone(index):
        serialize_message(linkage_marker_array(geometry, 0.01, angle(index), index,
                                               'shaper_base'))

    def markers_offset_moving(index):
        offset = 0.01 + 1e-7 * index
        serialize_message(linkage_marker_array(geometry, offset, angle(index), index,
                                               'shaper_base'))

    baseline = per_call_microseconds(joint_state_tick, args.calls, args.repeats)
    print(f'baseline joint-state tick (state + JointState + serialize): {baseline[0]:.1f} us '
          f'(spread {baseline[1]:.1f}-{baseline[2]:.1f}, median of {args.repeats} x '
          f'{args.calls} calls)')
    for name, function in (('markers, state passed in (+ state, serialize)', markers_with_state),
                           ('markers, state computed inside (+ serialize)', markers_alone),
                           ('markers, offset moving (+ serialize)', markers_offset_moving)):
        median, low, high = per_call_microseconds(function, args.calls, args.repeats)
        print(f'{name}: {median:.1f} us (spread {low:.1f}-{high:.1f}) = '
              f'{median / baseline[0]:.2f}x the tick; at 30 Hz {median * 30 / 1e4:.3f} % '
              'of a core')


if __name__ == '__main__':
    main()
