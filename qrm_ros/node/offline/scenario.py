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
A scenario for an offline run of shaper_sim: start-up parameters, a duration, timed events.

Written in YAML::

    parameters: {coupling_offset: 0.005, input_speed: 9.0}
    duration: 10.0            # s of simulated time
    start_time: 0.0           # s: the simulated clock's reading at the start
    events:
      - {at: 2.0, set: {coupling_offset: 0.01}}
      - {at: 4.0, input_speed_cmd: 6.0}
      - {at: 5.0, pause: true}
      - {at: 6.0, resume: true}
      - {at: 8.0, reset: true}

Only the form is checked here (names, numbers, times within the run); the values are judged
by the node itself, with its own rules and reasons, when the simulator starts it and when an
event sets them (qrm_ros.node.shaper_sim.shaper_parameters). ROS-free.
"""

import difflib
import math
from typing import Any, Dict, List, Mapping, NamedTuple, Optional, Tuple

import yaml

from qrm_ros.node.shaper_sim.shaper_parameters import PARAMETERS

__all__ = ['EVENT_KINDS', 'Event', 'MAX_DURATION', 'Scenario', 'ScenarioError', 'load_scenario',
           'parameter_value', 'scenario_from_mapping']

# What an event does; its value: set a mapping of parameters, command a speed (rad/s), or
# pause, resume or reset (true).
EVENT_KINDS = ('set', 'input_speed_cmd', 'pause', 'resume', 'reset')
# s: the longest run and the latest start accepted (stamps stay far inside int64 ns).
MAX_DURATION = 1e7
MAX_START_TIME = 1e9
# Parameters rclpy declares on every node, accepted beside the node's own.
RCLPY_PARAMETERS = ('use_sim_time',)


class ScenarioError(ValueError):
    """A scenario that cannot be run; the message is one line saying what and what is allowed."""


class Event(NamedTuple):
    """One timed event: at `at` s after the start, `kind` (EVENT_KINDS) with its value."""

    at: float
    kind: str
    value: Any


class Scenario(NamedTuple):
    """A whole offline run: start-up parameters, duration (s), start time (s), events."""

    parameters: Dict[str, Any]
    duration: float
    start_time: float = 0.0
    events: Tuple[Event, ...] = ()


def _number(value: Any, what: str, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f'{what} = {value!r} must be a number of seconds in '
                            f'[{low:g}, {high:g}] s')
    if not (math.isfinite(value) and low <= value <= high):
        raise ScenarioError(f'{what} = {value!r} s is outside [{low:g}, {high:g}] s')
    return float(value)


def _check_parameter_names(names: List[str], where: str) -> None:
    for name in names:
        if name in PARAMETERS or name in RCLPY_PARAMETERS:
            continue
        close = difflib.get_close_matches(str(name), PARAMETERS, n=1)
        hint = f' (did you mean {close[0]}?)' if close else ''
        raise ScenarioError(f'{where}: {name!r} is no parameter of shaper_sim{hint}; its '
                            f'parameters: {", ".join(sorted(PARAMETERS))}')


def parameter_value(name: str, value: Any) -> Any:
    """Take a YAML integer for a double parameter as that double (0 for 0.0), as the node does."""
    spec = PARAMETERS.get(name)
    if (spec is not None and isinstance(spec.default, float) and isinstance(value, int)
            and not isinstance(value, bool)):
        return float(value)
    return value


def _parameters(data: Any, where: str) -> Dict[str, Any]:
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise ScenarioError(f'{where} must be a mapping of parameter names to values, '
                            f'not {data!r}')
    names = [str(name) for name in data]
    _check_parameter_names(names, where)
    return {str(name): parameter_value(str(name), value) for name, value in data.items()}


def _event(item: Any, index: int, duration: float) -> Event:
    where = f'events[{index}]'
    if not isinstance(item, Mapping) or 'at' not in item:
        raise ScenarioError(f'{where} = {item!r} must be a mapping with "at" (s) and one of '
                            f'{", ".join(EVENT_KINDS)}')
    at = _number(item['at'], f'{where}.at', 0.0, duration)
    kinds = [key for key in item if key != 'at']
    if len(kinds) != 1 or kinds[0] not in EVENT_KINDS:
        raise ScenarioError(f'{where} has {kinds or "nothing"} besides "at": exactly one of '
                            f'{", ".join(EVENT_KINDS)} is allowed')
    kind = str(kinds[0])
    value = item[kind]
    if kind == 'set':
        value = _parameters(value, f'{where}.set')
        if not value:
            raise ScenarioError(f'{where}.set names no parameter: write set: {{name: value}}')
    elif kind == 'input_speed_cmd':
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(f'{where}.input_speed_cmd = {value!r} must be a number (rad/s)')
        value = float(value)  # the node judges its range (max_input_speed)
    elif value is not True:
        raise ScenarioError(f'{where}.{kind} = {value!r}: write {kind}: true')
    return Event(at, kind, value)


def scenario_from_mapping(data: Any, duration: Optional[float] = None,
                          parameters: Optional[Mapping[str, Any]] = None,
                          start_time: Optional[float] = None) -> Scenario:
    """
    Check a scenario's form and return it; ScenarioError says what is wrong.

    duration, parameters and start_time, when given, override the scenario's own (the
    command's --duration, -p and --start-time options).
    """
    data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ScenarioError(f'a scenario is a mapping with parameters, duration, start_time '
                            f'and events, not {type(data).__name__}')
    unknown = sorted(set(map(str, data)) - {'parameters', 'duration', 'start_time', 'events'})
    if unknown:
        raise ScenarioError(f'unknown scenario keys {unknown}: allowed parameters, duration, '
                            'start_time, events')
    if duration is None:
        if 'duration' not in data:
            raise ScenarioError('no duration: give the scenario a duration (s) or --duration')
        duration = data['duration']
    duration = _number(duration, 'duration', 0.0, MAX_DURATION)
    if duration <= 0.0:
        raise ScenarioError(f'duration = {duration!r} s must be > 0 s')
    if start_time is None:
        start_time = data.get('start_time', 0.0)
    start_time = _number(start_time, 'start_time', 0.0, MAX_START_TIME)
    values = _parameters(data.get('parameters'), 'parameters')
    values.update(_parameters(dict(parameters), '-p') if parameters else {})
    events = data.get('events') or []
    if not isinstance(events, list):
        raise ScenarioError(f'events must be a list of events, not {events!r}')
    checked = [_event(item, index, duration) for index, item in enumerate(events)]
    checked.sort(key=lambda event: event.at)  # stable: events at one time keep their order
    return Scenario(values, duration, start_time, tuple(checked))


def load_scenario(path: str, duration: Optional[float] = None,
                  parameters: Optional[Mapping[str, Any]] = None,
                  start_time: Optional[float] = None) -> Scenario:
    """Read a scenario file (YAML); ScenarioError names the file and what is wrong."""
    try:
        with open(path, encoding='utf-8') as handle:
            data = yaml.safe_load(handle)
    except OSError as error:
        raise ScenarioError(f'cannot read scenario {path!r}: {error.strerror}') from None
    except UnicodeDecodeError as error:  # a recording or another binary file, say
        raise ScenarioError(f'scenario {path!r} is not a text file (YAML, UTF-8): byte '
                            f'{error.start} is 0x{error.object[error.start]:02x}') from None
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        place = f' at line {mark.line + 1}' if mark is not None else ''
        raise ScenarioError(f'scenario {path!r} is not valid YAML{place}: '
                            f'{getattr(error, "problem", None) or error}') from None
    try:
        return scenario_from_mapping(data, duration, parameters, start_time)
    except ScenarioError as error:
        raise ScenarioError(f'scenario {path!r}: {error}') from None
