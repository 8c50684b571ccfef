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
"""exact_cdr: an rclpy message's CDR bytes as DDS sends them, by the type store's encoder."""

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterValue
from rosbags.serde import SerdeError
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from qrm_ros.recording.typestore import exact_cdr, jazzy_typestore

STORE = jazzy_typestore()
EVENT = 'rcl_interfaces/msg/ParameterEvent'
JOINT_STATE = 'sensor_msgs/msg/JointState'


def _reencoded(raw, type_name):
    """rclpy's bytes decoded by the store's own decoder (which stops where the message ends)
    and encoded again: the exact message with zero padding, found independently."""
    definition = STORE.get_msgdef(type_name)
    message, _ = definition.deserialize_cdr_le(memoryview(raw)[4:], 0, definition.cls, STORE)
    return bytes(STORE.serialize_cdr(message, type_name))


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
    with pytest.raises(SerdeError, match="size mismatch"):  # why exact_cdr exists
        STORE.deserialize_cdr(raw, EVENT)
    exact = exact_cdr(_rclpy_event(), EVENT)
    assert exact == bytes(STORE.serialize_cdr(_rosbags_event(), EVENT))
    assert exact == _reencoded(raw, EVENT)
    assert len(exact) < len(raw)
    assert deserialize_message(exact, ParameterEvent) == _rclpy_event()


def test_a_joint_state_keeps_its_values_and_gets_zero_padding():
    message = JointState(name=['input_joint', 'lever_joint'], position=[0.5, -1.25],
                         velocity=[6.25, 0.0], effort=[1e3, -2.5])
    message.header.frame_id = 'base'  # 4 + 5 bytes: padding follows
    exact = exact_cdr(message, JOINT_STATE)
    assert exact == _reencoded(serialize_message(message), JOINT_STATE)
    again = deserialize_message(exact, JointState)
    assert list(again.name) == list(message.name)
    for field in ('position', 'velocity', 'effort'):
        assert np.array_equal(getattr(again, field), getattr(message, field))


def _every_parameter_value():
    """Parameter values of every type, arrays empty and full."""
    return [ParameterValue(type=1, bool_value=True), ParameterValue(type=2, integer_value=-7),
            ParameterValue(type=4, string_value='zstd'),
            ParameterValue(type=5, byte_array_value=[b'\x00', b'\xff', b'\x07']),
            ParameterValue(type=6, bool_array_value=[True, False, True]),
            ParameterValue(type=7, integer_array_value=[1, -2, 3 ** 30]),
            ParameterValue(type=8, double_array_value=[0.1, -2.5e300, 0.0]),
            ParameterValue(type=9, string_array_value=['a', '', 'joint_states'])]


def _status(index):
    status = DiagnosticStatus(level=bytes([index % 4]), name=f'shaper_sim: pair {index}',
                              message='steady setting' * (index % 3), hardware_id='shaper')
    status.values = [KeyValue(key=f'key_{k}' * (k % 4), value=repr(0.1 * k * index))
                     for k in range(index * 7)]
    return status


def _markers():
    marker = Marker(ns='linkage', id=3, type=4, action=0, frame_locked=True, text='ram',
                    points=[Point(x=0.1 * k, y=-0.2, z=3.0) for k in range(5)],
                    colors=[ColorRGBA(r=1.0, g=0.5, b=0.25, a=1.0)] * 5,
                    lifetime=Duration(sec=1, nanosec=5))
    marker.header.frame_id = 'shaper_base'
    marker.pose.orientation.w = 1.0
    return MarkerArray(markers=[marker, Marker(action=3)])


@pytest.mark.parametrize('message, type_name', [
    (ParameterEvent(node='/n', new_parameters=[
        Parameter(name=f'p{index}', value=value)
        for index, value in enumerate(_every_parameter_value())],
        deleted_parameters=[Parameter(name='gone')]), EVENT),
    (DiagnosticArray(status=[_status(index) for index in range(5)]),
     'diagnostic_msgs/msg/DiagnosticArray'),
    (DiagnosticArray(), 'diagnostic_msgs/msg/DiagnosticArray'),
    (_markers(), 'visualization_msgs/msg/MarkerArray')])
def test_exact_cdr_is_rclpys_message_exactly(message, type_name):
    # Every kind of field the offline node writes this way: nested messages and their
    # sequences, strings, bytes, booleans, integers and floats single and in arrays.
    exact = exact_cdr(message, type_name)
    assert exact == _reencoded(serialize_message(message), type_name)
    assert deserialize_message(exact, type(message)) == message
