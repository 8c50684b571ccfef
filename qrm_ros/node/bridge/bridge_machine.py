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
The machine for the app's 3D panel, live: the URDF and its links' transforms (qrm_bridge).

Without a ROS installation nothing publishes ``/robot_description`` and ``/tf`` live (that is
``robot_state_publisher``'s work), and the shipped Foxglove layout draws the machine from
them. So, when the graph has no such publisher, the bridge serves them itself, as the recorder
writes them into a run (``recording.machine_transforms``): the URDF of the simulator's
geometry (read once from its parameters), its fixed joints on ``/tf_static``, and each joint
state's link transforms on ``/tf``, computed from the joint states' bytes only while a client
subscribes to ``/tf``. The two latched channels are sent again whenever a client subscribes.
"""

import threading
import time
from typing import Callable, Dict, Optional

from foxglove import Channel, Context, Schema
from rclpy.node import Node
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import (JOINT_STATES_TOPIC, ROBOT_DESCRIPTION_TOPIC,
                                       ROBOT_DESCRIPTION_TYPE, SIM_NODE_NAME, TF_MESSAGE_TYPE,
                                       TF_STATIC_TOPIC, TF_TOPIC)
from qrm_ros.node.bridge.bridge_parameters import NODE_SEPARATOR, ParameterBridge
from qrm_ros.node.bridge.bridge_topics import CDR, ROS2MSG
from qrm_ros.recording.machine_transforms import MachineMessages
from qrm_ros.recording.rosbag2_formats import (complete_definition, DEFINITION_DELIMITER,
                                               find_message_definition)

__all__ = ['MACHINE_TOPICS', 'MachineView', 'definition']

MACHINE_TOPICS = (ROBOT_DESCRIPTION_TOPIC, TF_STATIC_TOPIC, TF_TOPIC)
GEOMETRY_RETRY = 1.0  # s, between attempts to read the simulator's geometry


def definition(messages: MachineMessages, type_name: str) -> str:
    """
    Return the type's ros2msg text with the installed texts of its nested types.

    rosbags writes nested types without comments and defaults; a viewer that sees one nested
    type defined two ways (here and in the markers' schema) reports a changed schema.
    """
    text, _ = find_message_definition(type_name)  # installed: the same text as the recorder's
    if text is None:  # tf2_msgs is not installed without ROS: its own line, nested installed
        own = messages.definition(type_name).split('\n' + DEFINITION_DELIMITER)[0]
        text, _ = complete_definition(type_name, own)
    return text if text is not None else messages.definition(type_name)


class MachineView:
    """Serves the machine's URDF and transforms once the simulator's geometry is known."""

    def __init__(self, node: Node, context: Context, parameters: ParameterBridge,
                 subscribers: Callable[[int], int], reserve: Callable[[set], None],
                 sim_node: str = '/' + SIM_NODE_NAME):
        self._node, self._context, self._parameters = node, context, parameters
        self._subscribers, self._reserve = subscribers, reserve
        self._sim_node = sim_node
        self._messages: Optional[MachineMessages] = None
        self._ready: Optional[MachineMessages] = None  # made on the geometry thread
        self._channels: Dict[str, Channel] = {}
        self._sent_to: Dict[str, int] = {}  # latched topic -> subscribers when last sent
        self._joint_states: Optional[Subscription] = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_geometry, name='machine_geometry',
                                        daemon=True)
        self._thread.start()

    @property
    def serving(self) -> bool:
        return bool(self._channels)

    def _read_geometry(self) -> None:
        names = [self._sim_node + NODE_SEPARATOR + n for n in Geometry.field_names()]
        while not self._stop.is_set():
            values = {p.name.partition(NODE_SEPARATOR)[2]: p.get_value()
                      for p in self._parameters.get(names, quiet=True)}
            lengths = {name: value for name, value in values.items()
                       if isinstance(value, float)}
            if len(lengths) == len(names):
                try:
                    self._ready = MachineMessages(Geometry(**lengths))
                    return
                except ValueError as error:
                    self._node.get_logger().warning(f'no live machine drawing: {error}')
                    return
            self._stop.wait(GEOMETRY_RETRY)

    def tick(self, graph: Callable[[], Dict[str, list]]) -> None:
        """Advertise once the geometry is known; follow the clients (executor thread)."""
        if self._messages is None and self._ready is not None:
            if any(topic in graph() for topic in MACHINE_TOPICS):
                self._node.get_logger().info('the graph publishes the machine itself')
            else:
                self._start(self._ready)
                self._reserve(set(MACHINE_TOPICS))
            self._messages = self._ready
        messages = self._messages
        if not self._channels or messages is None:
            return
        for topic, payload in ((ROBOT_DESCRIPTION_TOPIC, messages.robot_description),
                               (TF_STATIC_TOPIC, lambda: messages.static_transforms(
                                   time.time_ns()))):
            count = self._subscribers(self._channels[topic].id())
            if count > self._sent_to.get(topic, 0):
                self._channels[topic].base.log(payload())
            self._sent_to[topic] = count
        wanted = self._subscribers(self._channels[TF_TOPIC].id()) > 0
        if wanted and self._joint_states is None:
            transforms, log = messages.transforms, self._channels[TF_TOPIC].base.log

            def on_joint_state(data: bytes) -> None:
                message = transforms(data)
                if message is not None:
                    log(message)
            self._joint_states = self._node.create_subscription(
                JointState, JOINT_STATES_TOPIC, on_joint_state, 100, raw=True)
        elif not wanted and self._joint_states is not None:
            self._node.destroy_subscription(self._joint_states)
            self._joint_states = None

    def _start(self, messages: MachineMessages) -> None:
        for topic, type_name in ((ROBOT_DESCRIPTION_TOPIC, ROBOT_DESCRIPTION_TYPE),
                                 (TF_STATIC_TOPIC, TF_MESSAGE_TYPE), (TF_TOPIC, TF_MESSAGE_TYPE)):
            schema = Schema(name=type_name, encoding=ROS2MSG,
                            data=definition(messages, type_name).encode())
            self._channels[topic] = Channel(topic, schema=schema, message_encoding=CDR,
                                            context=self._context)
        self._node.get_logger().info('serving the machine: its URDF on /robot_description and '
                                     'its transforms on /tf_static and /tf')

    def close(self) -> None:
        self._stop.set()
