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
"""canonical_cdr: rclpy's serialized bytes made the exact message, as DDS sends it."""

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterValue
from rosbags.serde import SerdeError
from sensor_msgs.msg import JointState

from qrm_ros.recording.typestore import canonical_cdr, jazzy_typestore

STORE = jazzy_typestore()
EVENT = 'rcl_interfaces/msg/ParameterEvent'
JOINT_STATE = 'sensor_msgs/msg/JointState'


def _rclpy_event():
    value = ParameterValue(type=3, double_value=-0.011172566371681417)
    event = ParameterEvent(node='/shaper_sim',
                           changed_parameters=[Parameter(name='coupling_offset', value=value)])
    event.stamp.sec, event.stamp.nanosec = 4, 990_000_000
    return event


def _rosbags_event():
    """The same event built in rosbags' own classes: an independent encoding."""
    types = STORE.types
    time = types['builtin_interfaces/msg/Time'](sec=4, nanosec=990_000_000)
    empty = {name: np.array([], dtype=kind) for name, kind in (
        ('byte_array_value', np.uint8), ('bool_array_value', np.bool_),
        ('integer_array_value', np.int64), ('double_array_value', np.float64))}
    value = types['rcl_interfaces/msg/ParameterValue'](
        type=3, bool_value=False, integer_value=0, double_value=-0.011172566371681417,
        string_value='', string_array_value=[], **empty)
    parameter = types['rcl_interfaces/msg/Parameter'](name='coupling_offset', value=value)
    return types[EVENT](stamp=time, node='/shaper_sim', new_parameters=[],
                        changed_parameters=[parameter], deleted_parameters=[])


def test_a_parameter_event_is_its_exact_bytes():
    raw = serialize_message(_rclpy_event())
    with pytest.raises(SerdeError, match="size mismatch"):  # why canonical_cdr exists
        STORE.deserialize_cdr(raw, EVENT)
    exact = canonical_cdr(raw, EVENT)
    assert exact == bytes(STORE.serialize_cdr(_rosbags_event(), EVENT))
    assert len(exact) < len(raw)
    assert deserialize_message(exact, ParameterEvent) == _rclpy_event()
    assert canonical_cdr(exact, EVENT) == exact


def test_a_joint_state_keeps_its_values_and_gets_zero_padding():
    message = JointState(name=['input_joint', 'lever_joint'], position=[0.5, -1.25],
                         velocity=[6.25, 0.0], effort=[1e3, -2.5])
    message.header.frame_id = 'base'  # 4 + 5 bytes: padding follows
    exact = canonical_cdr(serialize_message(message), JOINT_STATE)
    again = deserialize_message(exact, JointState)
    assert list(again.name) == list(message.name)
    for field in ('position', 'velocity', 'effort'):
        assert np.array_equal(getattr(again, field), getattr(message, field))
    decoded = STORE.deserialize_cdr(exact, JOINT_STATE)
    assert exact == bytes(STORE.serialize_cdr(decoded, JOINT_STATE))
