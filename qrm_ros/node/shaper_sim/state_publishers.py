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
What the shaper_sim node publishes every tick: the joint states and the ram's twist.

The messages are built once; each tick only fills in its values (the joints in
qrm_ros.core.common.names.PUBLISHED_JOINT_NAMES order).
"""

from array import array
import math

from geometry_msgs.msg import TwistStamped
from qrm_ros.core.common.names import JOINT_STATES_TOPIC, PUBLISHED_JOINT_NAMES, RAM_TWIST_TOPIC
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from rclpy.node import Node
from sensor_msgs.msg import JointState

__all__ = ['MIN_PUBLISHER_DEPTH', 'MechanismStatePublishers', 'PUBLISHER_HISTORY_SECONDS']

# Publisher history, in seconds of messages at the publish rate: a reliable subscriber that
# keeps up on average (the recorder) but stalls for a moment (a loaded machine) is resent
# what it missed instead of losing it, as KEEP_LAST 10 (0.01 s at 1 kHz) did.
PUBLISHER_HISTORY_SECONDS = 1.0
MIN_PUBLISHER_DEPTH = 10


class MechanismStatePublishers:
    """The joint_states and ram/twist publishers of a node, with their messages."""

    def __init__(self, node: Node, publish_rate: float):
        depth = max(MIN_PUBLISHER_DEPTH, math.ceil(PUBLISHER_HISTORY_SECONDS * publish_rate))
        self._joint_state = JointState(name=list(PUBLISHED_JOINT_NAMES))
        self._twist = TwistStamped()
        self._joint_state_publisher = node.create_publisher(JointState, JOINT_STATES_TOPIC,
                                                            depth)
        self._twist_publisher = node.create_publisher(TwistStamped, RAM_TWIST_TOPIC, depth)

    def publish(self, stamp_ns: int, frame_id: str, positions: array, velocities: array,
                efforts: array, ram_velocity: float) -> None:
        """Publish a sample: the joints' positions, velocities and efforts; the ram's speed."""
        seconds, nanoseconds = divmod(stamp_ns, NANOSECONDS_PER_SECOND)
        joint_state = self._joint_state
        joint_state.header.stamp.sec = seconds
        joint_state.header.stamp.nanosec = nanoseconds
        joint_state.header.frame_id = frame_id
        joint_state.position = positions
        joint_state.velocity = velocities
        joint_state.effort = efforts
        self._joint_state_publisher.publish(joint_state)
        twist = self._twist
        twist.header.stamp.sec = seconds
        twist.header.stamp.nanosec = nanoseconds
        twist.header.frame_id = frame_id
        twist.twist.linear.x = ram_velocity
        self._twist_publisher.publish(twist)
