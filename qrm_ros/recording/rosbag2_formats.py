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
The text formats rosbag2 (Jazzy) puts into an MCAP file, built here so its tools read ours.

- ``ros2msg`` schema text, as rosbag2's LocalMessageDefinitionSource builds it;
- the ``offered_qos_profiles`` channel metadata, as rosbag2_storage's
  serialize_rclcpp_qos_vector (metadata version 9) writes it;
- the ``serialized_metadata`` of the ``rosbag2`` metadata record.

Pure text: the MCAP run file, the recorder node and the recovery all build on these.
"""

import json
import os
import re
from typing import Callable, List, Optional, Sequence, Set, Tuple, TYPE_CHECKING

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError

from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

if TYPE_CHECKING:  # the recorder hands over rclpy's profiles; this module never imports ROS
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile

__all__ = ['DEFINITION_DELIMITER', 'complete_definition', 'find_message_definition',
           'find_service_definitions',
           'offered_qos_profiles_yaml', 'publisher_qos_profile_yaml', 'qos_profile_yaml_lines',
           'rosbag2_metadata_yaml', 'NO_QOS_PROFILES', 'TopicSummary']

DEFINITION_DELIMITER = '=' * 80 + '\n'
NO_QOS_PROFILES = '[]'
# Deepest nesting of message types followed before giving up (a cycle cannot be a message).
_MAX_NESTING = 50

# rosbag2's dependency scan of .msg text: a type at the start of a line, then whitespace.
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_TYPE_NAME = re.compile(r'^([a-zA-Z0-9_]+)/(?:msg/)?([a-zA-Z0-9_]+)$')
_SERVICE_NAME = re.compile(r'^([a-zA-Z0-9_]+)/srv/([a-zA-Z0-9_]+)$')
_SERVICE_SEPARATOR = re.compile(r'^---[ \t]*\r?\n?', re.MULTILINE)
_PRIMITIVE_TYPES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16',
                    'uint16', 'int32', 'uint32', 'int64', 'uint64', 'string'}


# --- schema text ---------------------------------------------------------------------------

def _msg_text(type_name: str, share_directory: Callable[[str], str]) -> Tuple[str, str]:
    match = _TYPE_NAME.match(type_name)
    if not match:
        raise LookupError(f'message type name {type_name!r} is not pkg/Type or pkg/msg/Type')
    package, name = match.groups()
    try:
        folder = share_directory(package)
    except (PackageNotFoundError, OSError):  # OSError: AMENT_PREFIX_PATH not set at all
        raise LookupError(f'package {package!r} of {type_name!r} is not in the ament index '
                          '(is AMENT_PREFIX_PATH set?)') from None
    path = os.path.join(folder, 'msg', name + '.msg')
    try:
        with open(path, encoding='utf-8', newline='') as handle:
            return package, handle.read()
    except OSError:
        raise LookupError(f'no message definition {path}') from None


def _msg_dependencies(text: str, package: str) -> List[str]:
    found = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVE_TYPES:
            continue
        found.add(field_type if '/' in field_type else package + '/' + field_type)
    return sorted(found)


def find_message_definition(
        type_name: str, share_directory: Callable[[str], str] = get_package_share_directory,
) -> Tuple[Optional[str], Optional[str]]:
    """
    Full ``ros2msg`` text of a type and None, or None and the reason it cannot be built.

    The text is the type's .msg text, then every nested type once (depth first, dependencies
    in sorted order, as rosbag2 does), each after a newline, a line of 80 '=' and
    ``MSG: pkg/Type``.
    """
    try:
        package, text = _msg_text(type_name, share_directory)
        return _with_dependencies(type_name, package, text, share_directory), None
    except LookupError as error:
        return None, str(error)


def complete_definition(type_name: str, text: str,
                        share_directory: Callable[[str], str] = get_package_share_directory,
                        ) -> Tuple[Optional[str], Optional[str]]:
    """
    Return a type's own .msg text completed with its nested types as find_message_definition does.

    For a type whose package is not installed but whose nested types are (``tf2_msgs``): the
    nested texts are then the installed ones, as every other channel of the same types has.
    """
    match = _TYPE_NAME.match(type_name)
    if not match:
        return None, f'message type name {type_name!r} is not pkg/Type or pkg/msg/Type'
    try:
        return _with_dependencies(type_name, match.group(1), text, share_directory), None
    except (LookupError, OSError) as error:
        return None, str(error)


def _with_dependencies(type_name: str, package: str, text: str,
                       share_directory: Callable[[str], str]) -> str:
    """Return the text, then every nested type once, as find_message_definition says."""
    seen: Set[str] = set()

    def append(package: str, text: str, depth: int) -> str:
        if depth <= 0:
            raise LookupError(f'nesting too deep resolving {type_name!r}')
        result = text
        for dependency in _msg_dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                result += '\n' + DEFINITION_DELIMITER + 'MSG: ' + dependency + '\n'
                result += append(*_msg_text(dependency, share_directory), depth - 1)
        return result

    return append(package, text, _MAX_NESTING)


def find_service_definitions(
        type_name: str, share_directory: Callable[[str], str] = get_package_share_directory,
) -> Tuple[Optional[Tuple[str, str]], Optional[str]]:
    """
    Full ``ros2msg`` texts of a service's request and response, and None; or None and why.

    ``pkg/srv/Type``'s .srv file split at its ``---`` line, each half completed with its
    nested types as find_message_definition completes a message.
    """
    match = _SERVICE_NAME.match(type_name)
    if not match:
        return None, f'service type name {type_name!r} is not pkg/srv/Type'
    package, name = match.groups()
    try:
        path = os.path.join(share_directory(package), 'srv', name + '.srv')
        with open(path, encoding='utf-8', newline='') as handle:
            halves = _SERVICE_SEPARATOR.split(handle.read(), maxsplit=1)
        if len(halves) != 2:
            return None, f'{path} has no --- line between request and response'
        return tuple(_with_dependencies(type_name, package, half, share_directory)
                     for half in halves), None  # type: ignore[return-value]
    except PackageNotFoundError:
        return None, f'package {package!r} of {type_name!r} is not in the ament index'
    except (OSError, LookupError) as error:
        return None, str(error)


# --- QoS metadata --------------------------------------------------------------------------

def _duration_yaml(duration: 'Duration', indent: str) -> str:
    seconds, nanoseconds = divmod(duration.nanoseconds, NANOSECONDS_PER_SECOND)
    return f'{indent}  sec: {seconds}\n{indent}  nsec: {nanoseconds}'


def qos_profile_yaml_lines(profile: 'QoSProfile') -> List[str]:
    """One QoS profile as the YAML block-sequence item rosbag2 writes (every field)."""
    # rclpy's short keys are rmw_qos_*_policy_to_str's spellings, which rosbag2 writes.
    lines = [
        f'- history: {profile.history.short_key}',
        f'  depth: {int(profile.depth)}',
        f'  reliability: {profile.reliability.short_key}',
        f'  durability: {profile.durability.short_key}',
        '  deadline:', _duration_yaml(profile.deadline, '  '),
        '  lifespan:', _duration_yaml(profile.lifespan, '  '),
        f'  liveliness: {profile.liveliness.short_key}',
        '  liveliness_lease_duration:', _duration_yaml(profile.liveliness_lease_duration, '  '),
        '  avoid_ros_namespace_conventions: '
        + ('true' if profile.avoid_ros_namespace_conventions else 'false'),
    ]
    return [line for text in lines for line in text.split('\n')]


def offered_qos_profiles_yaml(profiles: Sequence['QoSProfile']) -> str:
    """Return the ``offered_qos_profiles`` channel metadata value (yaml-cpp Dump style)."""
    if not profiles:
        return NO_QOS_PROFILES
    return '\n'.join(line for p in profiles for line in qos_profile_yaml_lines(p))


# rmw's "infinite" duration (RMW_DURATION_INFINITE), as a publisher's offered profile reports
# its unset deadline, lifespan and lease duration.
_INFINITE_SECONDS, _INFINITE_NANOSECONDS = divmod(2 ** 63 - 1, NANOSECONDS_PER_SECOND)


def publisher_qos_profile_yaml(reliability: str, durability: str) -> str:
    """
    One publisher's offered profile as rosbag2 records it, for messages written without ROS.

    What a discovered publisher reports: history unknown, depth 0, durations infinite, automatic
    liveliness; ``reliability`` 'reliable' or 'best_effort', ``durability`` 'volatile' or
    'transient_local' (a latched topic, replayed to late subscribers).
    """
    infinite = [f'    sec: {_INFINITE_SECONDS}', f'    nsec: {_INFINITE_NANOSECONDS}']
    return '\n'.join(['- history: unknown', '  depth: 0', f'  reliability: {reliability}',
                      f'  durability: {durability}', '  deadline:', *infinite, '  lifespan:',
                      *infinite, '  liveliness: automatic', '  liveliness_lease_duration:',
                      *infinite, '  avoid_ros_namespace_conventions: false'])


# --- the rosbag2 metadata record -----------------------------------------------------------

# A topic's (name, type, offered_qos_profiles YAML, type hash, message count).
TopicSummary = Tuple[str, str, str, str, int]


def _yaml_string(text: str) -> str:
    return json.dumps(text)  # a JSON string literal is a valid YAML double-quoted scalar


def rosbag2_metadata_yaml(path: str, topics: Sequence[TopicSummary], start_ns: int,
                          end_ns: int) -> str:
    """
    Build the ``serialized_metadata`` of rosbag2's ``rosbag2`` metadata record (version 9).

    ``topics`` is a list of (name, type, offered_qos_profiles YAML as in the channel
    metadata, type_hash, message_count).
    """
    count = sum(t[4] for t in topics)
    duration = max(0, end_ns - start_ns) if count else 0
    start = start_ns if count else 0
    name = _yaml_string(os.path.basename(path))
    lines = ['version: 9', 'storage_identifier: mcap', 'duration:',
             f'  nanoseconds: {duration}', 'starting_time:',
             f'  nanoseconds_since_epoch: {start}', f'message_count: {count}']
    if topics:
        lines.append('topics_with_message_count:')
        for topic, type_name, qos_yaml, type_hash, messages in topics:
            lines += ['  - topic_metadata:', f'      name: {_yaml_string(topic)}',
                      f'      type: {_yaml_string(type_name)}',
                      '      serialization_format: cdr']
            if qos_yaml and qos_yaml != NO_QOS_PROFILES:
                lines.append('      offered_qos_profiles:')
                lines += [' ' * 8 + line for line in qos_yaml.split('\n')]
            else:
                lines.append(f'      offered_qos_profiles: {NO_QOS_PROFILES}')
            lines += [f'      type_description_hash: {_yaml_string(type_hash)}',
                      f'    message_count: {messages}']
    else:
        lines.append('topics_with_message_count: []')
    lines += ['compression_format: ""', 'compression_mode: ""', 'relative_file_paths:',
              f'  - {name}', 'files:', f'  - path: {name}', '    starting_time:',
              f'      nanoseconds_since_epoch: {start}', '    duration:',
              f'      nanoseconds: {duration}', f'    message_count: {count}',
              'custom_data: {}',
              f'ros_distro: {_yaml_string(os.environ.get("ROS_DISTRO") or "jazzy")}']
    return '\n'.join(lines)
