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
"""The scenario's form: what is read, what overrides what, and one line for each mistake."""

import pytest

from qrm_ros.node.offline.scenario import (Event, load_scenario, scenario_from_mapping,
                                           ScenarioError)


def test_a_scenario_file_is_read_with_its_events_in_time_order(tmp_path):
    path = tmp_path / 'run.yaml'
    path.write_text('parameters: {coupling_offset: 0, drive: motor}\n'
                    'duration: 10\nstart_time: 5\n'
                    'events:\n'
                    '  - {at: 4.0, reset: true}\n'
                    '  - {at: 2, set: {coupling_offset: 0.01, cutting_force: 100}}\n'
                    '  - {at: 3.0, input_speed_cmd: 9}\n'
                    '  - {at: 3.0, pause: true}\n')
    scenario = load_scenario(str(path))
    # YAML integers for double parameters are doubles, as the node takes them.
    assert scenario.parameters == {'coupling_offset': 0.0, 'drive': 'motor'}
    assert isinstance(scenario.parameters['coupling_offset'], float)
    assert (scenario.duration, scenario.start_time) == (10.0, 5.0)
    assert scenario.events == (
        Event(2.0, 'set', {'coupling_offset': 0.01, 'cutting_force': 100.0}),
        Event(3.0, 'input_speed_cmd', 9.0), Event(3.0, 'pause', True),
        Event(4.0, 'reset', True))


def test_options_override_the_file():
    scenario = scenario_from_mapping({'duration': 3, 'parameters': {'input_speed': 3.0}},
                                     duration=7, parameters={'input_speed': 4.0},
                                     start_time=2.0)
    assert (scenario.duration, scenario.start_time) == (7.0, 2.0)
    assert scenario.parameters == {'input_speed': 4.0}


@pytest.mark.parametrize('data, message', [
    ({}, 'no duration'),
    ({'duration': 0}, r'duration = 0.0 s must be > 0 s'),
    ({'duration': float('nan')}, r'duration = nan s is outside \[0, 1e\+07\] s'),
    ({'duration': 'long'}, r"duration = 'long' must be a number of seconds"),
    ({'duration': 1, 'start_time': -1}, r'start_time = -1 s is outside \[0, 1e\+09\] s'),
    ({'duration': 1, 'speed': 3}, r"unknown scenario keys \['speed'\]"),
    ({'duration': 1, 'parameters': {'coupling_ofset': 0.0}},
     r"'coupling_ofset' is no parameter of shaper_sim \(did you mean coupling_offset\?\)"),
    ({'duration': 1, 'events': [{'at': 2, 'reset': True}]},
     r'events\[0\].at = 2 s is outside \[0, 1\] s'),
    ({'duration': 1, 'events': [{'at': 0.5}]}, r'exactly one of set, input_speed_cmd'),
    ({'duration': 1, 'events': [{'at': 0.5, 'reset': True, 'pause': True}]},
     'exactly one of'),
    ({'duration': 1, 'events': [{'at': 0.5, 'pause': 'yes'}]},
     r"events\[0\].pause = 'yes': write pause: true"),
    ({'duration': 1, 'events': [{'at': 0.5, 'input_speed_cmd': 'fast'}]},
     r'must be a number \(rad/s\)'),
    ({'duration': 1, 'events': [{'at': 0.5, 'set': {}}]}, 'names no parameter'),
    ({'duration': 1, 'events': {'at': 0.5}}, 'events must be a list'),
    ([1, 2], 'a scenario is a mapping'),
])
def test_mistakes_are_refused_in_one_line(data, message):
    with pytest.raises(ScenarioError, match=message) as refused:
        scenario_from_mapping(data)
    assert '\n' not in str(refused.value)


def test_a_file_that_is_no_yaml_is_named(tmp_path):
    path = tmp_path / 'broken.yaml'
    path.write_text('duration: [1\n')
    with pytest.raises(ScenarioError, match=r"scenario '.*broken.yaml' is not valid YAML"):
        load_scenario(str(path))
    with pytest.raises(ScenarioError, match='cannot read scenario'):
        load_scenario(str(tmp_path / 'missing.yaml'))


def test_a_file_that_is_not_text_is_named(tmp_path):
    # A recording given as the scenario by mistake: its first byte is MCAP's magic (0x89).
    path = tmp_path / 'run.mcap'
    path.write_bytes(b'\x89MCAP0\r\n' + bytes(range(256)))
    with pytest.raises(ScenarioError, match=r"scenario '.*run.mcap' is not a text file "
                                            r'\(YAML, UTF-8\): byte 0 is 0x89'):
        load_scenario(str(path))
