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
Service definitions in the ros2msg form (what qrm_bridge advertises for a service's halves).

Checked with another reader: mcap_ros2's own ros2msg parser builds a decoder from each text,
and it must read back what rclpy serialized.
"""

from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
import pytest
from qrm_ros.recording.rosbag2_formats import (DEFINITION_DELIMITER, find_message_definition,
                                               find_service_definitions)
from rcl_interfaces.msg import Parameter, ParameterValue, SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.serialization import serialize_message
from std_srvs.srv import SetBool, Trigger


def _decoded(type_name, text, message):
    schema = Schema(id=1, name=type_name, encoding='ros2msg', data=text.encode())
    return DecoderFactory().decoder_for('cdr', schema)(serialize_message(message))


def test_each_half_of_a_service_reads_what_rclpy_serialized():
    (request_text, response_text), problem = find_service_definitions(
        'rcl_interfaces/srv/SetParameters')
    assert problem is None
    request = SetParameters.Request(parameters=[Parameter(
        name='coupling_offset', value=ParameterValue(type=3, double_value=0.0125))])
    read = _decoded('rcl_interfaces/srv/SetParameters_Request', request_text, request)
    assert read.parameters[0].name == 'coupling_offset'
    assert read.parameters[0].value.double_value == 0.0125
    response = SetParameters.Response(results=[SetParametersResult(successful=False,
                                                                   reason='outside')])
    read = _decoded('rcl_interfaces/srv/SetParameters_Response', response_text, response)
    assert (read.results[0].successful, read.results[0].reason) == (False, 'outside')
    # A nested type follows as the message definitions write it.
    nested = find_message_definition('rcl_interfaces/msg/SetParametersResult')[0]
    assert response_text.endswith(
        DEFINITION_DELIMITER + 'MSG: rcl_interfaces/SetParametersResult\n' + nested)


def test_the_shaper_services_and_an_empty_request():
    (request_text, response_text), _ = find_service_definitions('std_srvs/srv/SetBool')
    assert _decoded('std_srvs/srv/SetBool_Request', request_text,
                    SetBool.Request(data=True)).data is True
    answer = _decoded('std_srvs/srv/SetBool_Response', response_text,
                      SetBool.Response(success=True, message='paused'))
    assert (answer.success, answer.message) == (True, 'paused')
    (request_text, response_text), _ = find_service_definitions('std_srvs/srv/Trigger')
    assert request_text == ''
    assert _decoded('std_srvs/srv/Trigger_Response', response_text,
                    Trigger.Response(success=True, message='reset')).message == 'reset'


@pytest.mark.parametrize('type_name, words', [
    ('std_srvs/SetBool', 'is not pkg/srv/Type'),
    ('std_srvs/msg/SetBool', 'is not pkg/srv/Type'),
    ('no_such_package/srv/X', "package 'no_such_package'"),
    ('std_srvs/srv/NoSuchService', 'NoSuchService.srv'),
])
def test_what_cannot_be_found_is_said(type_name, words):
    texts, problem = find_service_definitions(type_name)
    assert texts is None and words in problem


def test_an_ament_index_not_set_at_all_is_said():
    def unset(package):
        raise OSError("Environment variable 'AMENT_PREFIX_PATH' is not set or empty")
    text, problem = find_message_definition('std_msgs/msg/String', share_directory=unset)
    assert text is None and 'is AMENT_PREFIX_PATH set?' in problem
