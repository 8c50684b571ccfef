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
Writes the machine (``machine_transforms``) into a run file beside its joint states.

Whoever writes the run file (the recorder, or anything else writing the same file) hands over
each joint state as it writes it, and the geometry once it knows it. The geometry comes from
the sim's parameters, a little after the first joint states: until then the joint states are
remembered (a bounded number), and once it is known the URDF and the fixed transforms are
written at the first joint state's log time and the waiting transforms at their own, so the
machine is there from the first message. Messages then overlap in log time across a chunk
or two, which MCAP's index and every reader of it allow for.
"""

from collections import deque
from typing import Deque, Optional, Sequence, Tuple

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import (ROBOT_DESCRIPTION_TOPIC, ROBOT_DESCRIPTION_TYPE,
                                       TF_MESSAGE_TYPE, TF_STATIC_TOPIC, TF_TOPIC)
from qrm_ros.recording.machine_transforms import MachineMessages
from qrm_ros.recording.mcap_run_file import McapRunFile
from qrm_ros.recording.rosbag2_formats import publisher_qos_profile_yaml

__all__ = ['MAX_WAITING_JOINT_STATES', 'MachineChannels']

# Joint states remembered while the geometry is not known (it usually comes within a second):
# 5 s at 1 kHz, about 1 MB. Past that the oldest go without transforms (the sim is slow to say
# its geometry, or never does: a publisher that is not ours).
MAX_WAITING_JOINT_STATES = 5000
LATCHED = publisher_qos_profile_yaml('reliable', 'transient_local')
STREAMED = publisher_qos_profile_yaml('reliable', 'volatile')


class MachineChannels:
    """The /robot_description, /tf_static and /tf channels of one run file."""

    def __init__(self, run_file: McapRunFile) -> None:
        self._run_file = run_file
        self._messages: Optional[MachineMessages] = None
        self._tf_channel = 0
        # (log time, publish time, data) of the joint states before the geometry
        self._waiting: Deque[Tuple[int, int, bytes]] = deque()
        self.dropped = 0  # joint states without transforms (undecodable, or too many waiting)

    @property
    def started(self) -> bool:
        """Whether the geometry is known and the machine's channels are written."""
        return self._messages is not None

    def joint_state(self, log_time: int, publish_time: int, data: bytes) -> None:
        """Add the transforms of a joint state just written (or keep it until the geometry)."""
        if self._messages is None:
            if len(self._waiting) >= MAX_WAITING_JOINT_STATES:
                self._waiting.popleft()
                self.dropped += 1
            self._waiting.append((log_time, publish_time, data))
            return
        transforms = self._messages.transforms(data)
        if transforms is None:
            self.dropped += 1
            return
        self._run_file.add_message(self._tf_channel, log_time, publish_time, transforms)

    def joint_state_values(self, log_time: int, publish_time: int, data: bytes, sec: int,
                           nanosec: int, names: Sequence[str],
                           positions: Sequence[float]) -> None:
        """
        joint_state() for a writer that holds the message's stamp and values, not only data.

        The transforms are the same as joint_state() finds by decoding data (the writer's own
        message need not be decoded again); before the geometry, data waits as there.
        """
        messages = self._messages
        if messages is None:
            self.joint_state(log_time, publish_time, data)
            return
        transforms = messages.joint_transforms(sec, nanosec, names, positions)
        if transforms is None:
            self.dropped += 1
            return
        self._run_file.add_message(self._tf_channel, log_time, publish_time, transforms)

    def start(self, geometry: Geometry, now_ns: int) -> None:
        """
        Write the URDF and fixed transforms of this geometry, then the waiting transforms.

        They are logged at the first joint state's log time (now_ns if none came yet) and
        stamped with its stamp.
        """
        if self._messages is not None:
            return
        messages = MachineMessages(geometry)
        run_file = self._run_file
        channels = {}
        for topic, type_name, qos in ((ROBOT_DESCRIPTION_TOPIC, ROBOT_DESCRIPTION_TYPE, LATCHED),
                                      (TF_STATIC_TOPIC, TF_MESSAGE_TYPE, LATCHED),
                                      (TF_TOPIC, TF_MESSAGE_TYPE, STREAMED)):
            run_file.add_schema(type_name, messages.definition(type_name))
            channels[topic] = run_file.add_channel(topic, type_name, qos,
                                                   messages.type_hash(type_name))
        first = self._waiting[0] if self._waiting else None
        log_time = first[0] if first else now_ns
        stamp = messages.joint_state_stamp(first[2]) if first else None
        stamp = log_time if stamp is None else stamp
        run_file.add_message(channels[ROBOT_DESCRIPTION_TOPIC], log_time, log_time,
                             messages.robot_description())
        run_file.add_message(channels[TF_STATIC_TOPIC], log_time, log_time,
                             messages.static_transforms(stamp))
        self._messages, self._tf_channel = messages, channels[TF_TOPIC]
        waiting, self._waiting = self._waiting, deque()
        for log_time, publish_time, data in waiting:
            self.joint_state(log_time, publish_time, data)
