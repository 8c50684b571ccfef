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
The machine in a run file: its URDF and its links' transforms, for viewers that draw it.

What ``robot_state_publisher`` would publish for the model of ``urdf_model``: each joint
state's moving joints as link transforms on ``/tf``, the fixed joints once on ``/tf_static``
and the URDF once on ``/robot_description`` (both latched), so Foxglove, RViz after
``ros2 bag play``, or any tf reader sees the machine, moving, from the first joint state.
A transform is the joint's origin and its motion by the recorded value (a turn about the
axis, or a slide along it), the URDF's own forward kinematics; the joint values are the
node's, which are the core's kinematics at each stamp.

The messages are ROS 2 types in CDR, encoded and decoded by rosbags (its Jazzy type store
holds ``tf2_msgs``, which is not on the package index), so every reader of the run file,
rosbags included, reads them as it reads the rest.
"""

import math
import threading
from typing import Any, List, Mapping, NamedTuple, Optional, Sequence, Tuple

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import (CRANK_RADIUS_JOINT, JOINT_STATE_TYPE, PUBLISHED_JOINT_NAMES,
                                       ROBOT_DESCRIPTION_TYPE, TF_MESSAGE_TYPE)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.typestore import jazzy_typestore
from qrm_ros.recording.urdf_model import urdf_joints, urdf_text, UrdfJoint

__all__ = ['LinkTransform', 'MachineMessages', 'fixed_transforms', 'joint_transform',
           'moving_transforms']


class LinkTransform(NamedTuple):
    """The pose of a child link in its parent's frame (m; unit quaternion x, y, z, w)."""

    parent: str
    child: str
    translation: Tuple[float, float, float]
    rotation: Tuple[float, float, float, float]


def joint_transform(joint: UrdfJoint, value: float = 0.0) -> LinkTransform:
    """Return the child link's pose for a joint value (rad or m; ignored for a fixed joint)."""
    x, y, z = joint.origin
    translation, rotation = (x, y, z), (0.0, 0.0, 0.0, 1.0)
    if joint.kind == 'prismatic':
        translation = _slid(joint.origin, joint.axis or (0.0, 0.0, 0.0), value)
    elif joint.kind in _TURNING:
        rotation = _turned(joint.axis or (0.0, 0.0, 0.0), value)
    return LinkTransform(joint.parent, joint.child, translation, rotation)


_TURNING = ('revolute', 'continuous')


def _slid(origin: Sequence[float], axis: Sequence[float],
          value: float) -> Tuple[float, float, float]:
    """Return a slide's translation: the origin moved along the axis by the value (m)."""
    return (origin[0] + axis[0] * value, origin[1] + axis[1] * value,
            origin[2] + axis[2] * value)


def _turned(axis: Sequence[float], value: float) -> Tuple[float, float, float, float]:
    """Return a turn's rotation: the unit quaternion of the value (rad) about the axis."""
    sine = math.sin(0.5 * value)
    return axis[0] * sine, axis[1] * sine, axis[2] * sine, math.cos(0.5 * value)


def fixed_transforms(geometry: Geometry) -> List[LinkTransform]:
    """Return the fixed joints' transforms (the pins on their links)."""
    return [joint_transform(joint) for joint in urdf_joints(geometry).values()
            if joint.kind == 'fixed']


def moving_transforms(geometry: Geometry,
                      positions: Mapping[str, float]) -> List[LinkTransform]:
    """
    Return the moving joints' transforms for joint values by name (every one needed).

    The crank radius's joint may be missing (a publisher made before the stroke could move):
    it is then the geometry's crank radius.
    """
    positions = dict(positions)
    positions.setdefault(CRANK_RADIUS_JOINT, float(geometry.crank_radius))
    return [joint_transform(joint, positions[joint.name])
            for joint in urdf_joints(geometry).values() if joint.kind != 'fixed']


class MachineMessages:
    """The CDR messages of the machine with one geometry: URDF, fixed and moving transforms."""

    def __init__(self, geometry: Geometry) -> None:
        self.geometry = geometry
        self._joints = [j for j in urdf_joints(geometry).values() if j.kind != 'fixed']
        moving = {joint.name for joint in self._joints}
        if moving != set(PUBLISHED_JOINT_NAMES):
            raise ValueError(f'the URDF\'s moving joints {sorted(moving)} are not the '
                             f'published ones {sorted(PUBLISHED_JOINT_NAMES)}')
        self._store = jazzy_typestore()
        types = self._store.types
        self._time = types['builtin_interfaces/msg/Time']
        self._header = types['std_msgs/msg/Header']
        self._stamped = types['geometry_msgs/msg/TransformStamped']
        self._transform = types['geometry_msgs/msg/Transform']
        self._vector = types['geometry_msgs/msg/Vector3']
        self._quaternion = types['geometry_msgs/msg/Quaternion']
        self._tf_message = types[TF_MESSAGE_TYPE]
        self._string = types[ROBOT_DESCRIPTION_TYPE]
        # The moving links' TFMessage, built once; each joint state only sets its numbers
        # (rosbags serializes what the objects hold), one caller at a time.
        self._moving_stamp = self._time(sec=0, nanosec=0)
        self._moving = self._tf_message(transforms=[self._stamped(
            header=self._header(stamp=self._moving_stamp, frame_id=joint.parent),
            child_frame_id=joint.child, transform=self._transform(
                translation=self._vector(x=0.0, y=0.0, z=0.0),
                rotation=self._quaternion(x=0.0, y=0.0, z=0.0, w=1.0)))
            for joint in self._joints])
        self._moving_lock = threading.Lock()
        # What a joint value moves in each moving transform, the rest of it kept as built:
        # a slide's translation, a turn's rotation (joint_transform's _slid and _turned),
        # without a LinkTransform per joint per joint state.
        self._movers: List[Tuple[bool, bool, Tuple[float, ...], Tuple[float, ...], Any]] = []
        for stamped, joint in zip(self._moving.transforms, self._joints):
            link = joint_transform(joint)
            translation, rotation = stamped.transform.translation, stamped.transform.rotation
            translation.x, translation.y, translation.z = link.translation
            rotation.x, rotation.y, rotation.z, rotation.w = link.rotation
            slides = joint.kind == 'prismatic'
            turns = joint.kind in _TURNING  # else it moves nothing
            self._movers.append((slides, turns, tuple(joint.origin),
                                 tuple(joint.axis or (0.0, 0.0, 0.0)),
                                 translation if slides else rotation))
        # Where each moving joint's value is in a joint state in the published order.
        self._published_index = [PUBLISHED_JOINT_NAMES.index(joint.name)
                                 for joint in self._joints]

    def definition(self, type_name: str) -> str:
        """Return the ``ros2msg`` schema text of a type written here (from rosbags)."""
        return self._store.generate_msgdef(type_name, ros_version=2)[0]

    def type_hash(self, type_name: str) -> str:
        """Return the type's RIHS01 hash, as a publisher of it would report."""
        return self._store.hash_rihs01(type_name)

    def robot_description(self) -> bytes:
        """Return the URDF as a std_msgs/String."""
        return bytes(self._store.serialize_cdr(self._string(data=urdf_text(self.geometry)),
                                               ROBOT_DESCRIPTION_TYPE))

    def _encode(self, transforms: Sequence[LinkTransform], sec: int, nanosec: int) -> bytes:
        stamp = self._time(sec=sec, nanosec=nanosec)
        message = self._tf_message(transforms=[
            self._stamped(header=self._header(stamp=stamp, frame_id=t.parent),
                          child_frame_id=t.child,
                          transform=self._transform(
                              translation=self._vector(x=t.translation[0], y=t.translation[1],
                                                       z=t.translation[2]),
                              rotation=self._quaternion(x=t.rotation[0], y=t.rotation[1],
                                                        z=t.rotation[2], w=t.rotation[3])))
            for t in transforms])
        return bytes(self._store.serialize_cdr(message, TF_MESSAGE_TYPE))

    def static_transforms(self, stamp_ns: int) -> bytes:
        """Return the fixed joints' transforms as a TFMessage stamped stamp_ns."""
        sec, nanosec = divmod(stamp_ns, NANOSECONDS_PER_SECOND)
        return self._encode(fixed_transforms(self.geometry), sec, nanosec)

    def joint_state_stamp(self, joint_state: bytes) -> Optional[int]:
        """Return a recorded JointState's header stamp (ns), or None if undecodable."""
        try:
            stamp = self._store.deserialize_cdr(joint_state, JOINT_STATE_TYPE).header.stamp
        except Exception:  # rosbags raises its own errors (and struct's, IndexError) on odd bytes
            return None
        return stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec

    def transforms(self, joint_state: bytes) -> Optional[bytes]:
        """
        Return the moving links' transforms of a recorded JointState, stamped as it is.

        None when it cannot be decoded, lacks a moving joint or holds a non-finite position:
        nothing is then written for it, as a viewer would draw it wrong.
        """
        try:
            message = self._store.deserialize_cdr(joint_state, JOINT_STATE_TYPE)
        except Exception:  # rosbags raises its own errors (and struct's, IndexError) on odd bytes
            return None
        stamp = message.header.stamp
        return self.joint_transforms(stamp.sec, stamp.nanosec, message.name, message.position)

    def joint_transforms(self, sec: int, nanosec: int, names: Sequence[str],
                         positions: Sequence[float]) -> Optional[bytes]:
        """
        Return the moving links' transforms of joint values by name, stamped sec, nanosec.

        What transforms() does once the joint state is decoded (a writer that holds the
        values need not decode its own message): None when a moving joint is missing or a
        value is not finite.
        """
        if (len(positions) == len(names) == len(PUBLISHED_JOINT_NAMES)
                and tuple(names) == PUBLISHED_JOINT_NAMES):
            values = [float(positions[index]) for index in self._published_index]
        else:
            by_name = dict(zip(names, (float(p) for p in positions)))
            # A publisher without the crank radius's joint (made before the stroke could
            # move) has the geometry's crank radius.
            by_name.setdefault(CRANK_RADIUS_JOINT, float(self.geometry.crank_radius))
            try:
                values = [by_name[joint.name] for joint in self._joints]
            except KeyError:
                return None
        if not all(map(math.isfinite, values)):
            return None
        with self._moving_lock:
            self._moving_stamp.sec, self._moving_stamp.nanosec = sec, nanosec
            for (slides, turns, origin, axis, moved), value in zip(self._movers, values):
                if slides:
                    moved.x, moved.y, moved.z = _slid(origin, axis, value)
                elif turns:
                    moved.x, moved.y, moved.z, moved.w = _turned(axis, value)
            return bytes(self._store.serialize_cdr(self._moving, TF_MESSAGE_TYPE))
