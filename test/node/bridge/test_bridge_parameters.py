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
"""ROS parameter values <-> Foxglove parameters, and parameter names (qrm_bridge)."""

from foxglove import ParameterType as FoxgloveType
import pytest
from qrm_ros.node.bridge.bridge_parameters import from_ros, ParameterRefusal, split_name, to_ros
from rcl_interfaces.msg import ParameterType, ParameterValue
from rclpy.parameter import Parameter, parameter_value_to_python


@pytest.mark.parametrize('value', [True, 7, -2.5, 0.0, 'motor', [True, False], [1, 2, 3],
                                   [0.5, 1.0], ['a', 'b']])
def test_a_value_goes_to_ros_and_back_as_rclpy_types_it(value):
    ros = to_ros(value)
    # rclpy's own typing of the same Python value is the independent reference.
    assert ros.type == Parameter('x', value=value).type_.value
    assert parameter_value_to_python(ros) == value
    back = from_ros('/node.x', ros).get_value()
    assert back == value and type(back) is type(value)


def test_a_whole_number_for_a_double_parameter_is_that_double():
    assert to_ros(0).type == ParameterType.PARAMETER_INTEGER
    double = to_ros(0, ParameterType.PARAMETER_DOUBLE)
    assert (double.type, double.double_value) == (ParameterType.PARAMETER_DOUBLE, 0.0)
    array = to_ros([1, 2], ParameterType.PARAMETER_DOUBLE_ARRAY)
    assert list(array.double_array_value) == [1.0, 2.0]
    assert from_ros('/n.d', double).type == FoxgloveType.Float64  # 0.0 stays a double


def test_bytes_and_unset_values():
    ros = to_ros(b'\x01\xff')
    assert ros.type == ParameterType.PARAMETER_BYTE_ARRAY
    assert from_ros('/n.b', ros).get_value() == b'\x01\xff'
    assert from_ros('/n.unset', ParameterValue()).get_value() is None


@pytest.mark.parametrize('value', [None, {'a': 1}, [], [1, 'a'], [[1]]])
def test_a_value_without_a_ros_type_is_refused_saying_what_is_allowed(value):
    with pytest.raises(ParameterRefusal, match='has no ROS parameter type'):
        to_ros(value)


def test_names_are_node_dot_parameter():
    assert split_name('/shaper_sim.coupling_offset') == ('/shaper_sim', 'coupling_offset')
    assert split_name('/ns/node.qos_overrides./x.depth') == ('/ns/node', 'qos_overrides./x.depth')
    for bad in ('coupling_offset', 'shaper_sim.x', '/shaper_sim.', '/shaper_sim'):
        with pytest.raises(ParameterRefusal, match='is not /node.parameter'):
            split_name(bad)
