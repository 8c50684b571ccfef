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
The ``mcap_recorder`` node: records a shaper_sim run to an MCAP file in rosbag2's form.

The file is what rosbag2's MCAP storage plugin (Jazzy) writes, so ``ros2 bag info/play``,
Foxglove and the ``rosbags`` library open it unchanged: profile ``ros2``, the CDR bytes exactly
as received, ``ros2msg`` schemas built like rosbag2 builds them, channel metadata
``offered_qos_profiles`` and ``topic_type_hash``, chunks with message indexes, a summary with
statistics, and a ``rosbag2`` metadata record on a clean finish. On top of that the run is made
self-describing with two metadata records read from the sim node's parameter services:
``qrm_ros.geometry`` (the five geometry parameters, ``repr(float)`` strings) and
``qrm_ros.parameters`` (every parameter, JSON-encoded).

Chunks are closed (and fsynced) whenever ``max_chunk_duration`` seconds of log time have
passed, so SIGKILL or power loss costs at most that much; ``qrm_ros.bag_reader`` reads such an
unfinished file up to its last whole chunk.
"""

import datetime
import importlib
import json
import math
import os
import re
import signal
import sys
import time

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from mcap.writer import CompressionType, Writer
from rcl_interfaces.msg import ParameterDescriptor
from rcl_interfaces.srv import GetParameters, ListParameters
import rclpy
from rclpy.exceptions import NameValidationException, ParameterException
import rclpy.executors
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)
from rclpy.signals import SignalHandlerOptions

from qrm_ros.kinematics import Geometry
from qrm_ros.names import (DIAGNOSTICS_TOPIC, GEOMETRY_METADATA, JOINT_STATES_TOPIC,
                           PARAMETERS_METADATA, RAM_TWIST_TOPIC, RECORDER_NODE_NAME,
                           SPEED_COMMAND_TOPIC)

NODE_NAME = RECORDER_NODE_NAME
DEFAULT_TOPICS = [JOINT_STATES_TOPIC, RAM_TWIST_TOPIC, SPEED_COMMAND_TOPIC, DIAGNOSTICS_TOPIC,
                  '/parameter_events']
COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}
GEOMETRY_PARAMETERS = list(Geometry.field_names())
MAX_CHUNK_DURATION_RANGE = (0.001, 3600.0)
# Closing a chunk early by size keeps memory bounded at high rates; duration is the usual limit.
CHUNK_SIZE_BYTES = 4 * 1024 * 1024
# Deep reader queue: a Python callback can lag a 1 kHz burst; KEEP_LAST 10 would drop then.
SUBSCRIPTION_DEPTH = 1000
TOPIC_POLL_PERIOD = 0.1
DEFINITION_DELIMITER = '=' * 80 + '\n'

# rmw_qos_*_policy_to_str spellings (rosbag2 metadata version 9), keyed by rclpy enum value.
_HISTORY_NAMES = {HistoryPolicy.SYSTEM_DEFAULT: 'system_default',
                  HistoryPolicy.KEEP_LAST: 'keep_last', HistoryPolicy.KEEP_ALL: 'keep_all'}
_RELIABILITY_NAMES = {ReliabilityPolicy.SYSTEM_DEFAULT: 'system_default',
                      ReliabilityPolicy.RELIABLE: 'reliable',
                      ReliabilityPolicy.BEST_EFFORT: 'best_effort',
                      ReliabilityPolicy.BEST_AVAILABLE: 'best_available'}
_DURABILITY_NAMES = {DurabilityPolicy.SYSTEM_DEFAULT: 'system_default',
                     DurabilityPolicy.TRANSIENT_LOCAL: 'transient_local',
                     DurabilityPolicy.VOLATILE: 'volatile',
                     DurabilityPolicy.BEST_AVAILABLE: 'best_available'}
_LIVELINESS_NAMES = {LivelinessPolicy.SYSTEM_DEFAULT: 'system_default',
                     LivelinessPolicy.AUTOMATIC: 'automatic',
                     LivelinessPolicy.MANUAL_BY_TOPIC: 'manual_by_topic',
                     LivelinessPolicy.BEST_AVAILABLE: 'best_available'}

# rosbag2's dependency scan of .msg text: a type at the start of a line, then whitespace.
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_TYPE_NAME = re.compile(r'^([a-zA-Z0-9_]+)/(?:msg/)?([a-zA-Z0-9_]+)$')
_PRIMITIVE_TYPES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16',
                    'uint16', 'int32', 'uint32', 'int64', 'uint64', 'string'}


class RecorderError(Exception):
    """A condition that ends the recording with a one-line message and a non-zero exit."""


# --- schema text, as rosbag2's LocalMessageDefinitionSource builds it ----------------------

def _load_msg_text(type_name, share_directory):
    match = _TYPE_NAME.match(type_name)
    if not match:
        raise LookupError(f'message type name {type_name!r} is not pkg/Type or pkg/msg/Type')
    package, name = match.groups()
    try:
        folder = share_directory(package)
    except PackageNotFoundError:
        raise LookupError(f'package {package!r} of {type_name!r} is not in the ament index '
                          '(is AMENT_PREFIX_PATH set?)') from None
    path = os.path.join(folder, 'msg', name + '.msg')
    try:
        with open(path, encoding='utf-8', newline='') as handle:
            return package, handle.read()
    except OSError:
        raise LookupError(f'no message definition {path}') from None


def _msg_dependencies(text, package):
    found = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVE_TYPES:
            continue
        found.add(field_type if '/' in field_type else package + '/' + field_type)
    return sorted(found)


def message_definition(type_name, share_directory=get_package_share_directory):
    """
    Full ``ros2msg`` text of a type: its .msg text, then every nested type once.

    Each nested type (depth first, dependencies in sorted order, as rosbag2 does) follows a
    newline, a line of 80 '=', and ``MSG: pkg/Type``. Raises LookupError if a .msg is missing.
    """
    seen = set()

    def append(name, depth):
        if depth <= 0:
            raise LookupError(f'nesting too deep resolving {type_name!r}')
        package, text = _load_msg_text(name, share_directory)
        result = text
        for dependency in _msg_dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                result += '\n' + DEFINITION_DELIMITER + 'MSG: ' + dependency + '\n'
                result += append(dependency, depth - 1)
        return result

    return append(type_name, 50)


# --- QoS metadata, as rosbag2_storage::serialize_rclcpp_qos_vector (version 9) writes it -----

def _duration_yaml(duration, indent):
    nanoseconds = duration.nanoseconds
    return (f'{indent}  sec: {nanoseconds // 1_000_000_000}\n'
            f'{indent}  nsec: {nanoseconds % 1_000_000_000}')


def qos_profile_yaml_lines(profile, indent=''):
    """One QoS profile as the YAML block-sequence item rosbag2 writes (every field)."""
    lines = [
        f'- history: {_HISTORY_NAMES.get(profile.history, "unknown")}',
        f'  depth: {int(profile.depth)}',
        f'  reliability: {_RELIABILITY_NAMES.get(profile.reliability, "unknown")}',
        f'  durability: {_DURABILITY_NAMES.get(profile.durability, "unknown")}',
        '  deadline:', _duration_yaml(profile.deadline, '  '),
        '  lifespan:', _duration_yaml(profile.lifespan, '  '),
        f'  liveliness: {_LIVELINESS_NAMES.get(profile.liveliness, "unknown")}',
        '  liveliness_lease_duration:', _duration_yaml(profile.liveliness_lease_duration, '  '),
        '  avoid_ros_namespace_conventions: '
        + ('true' if profile.avoid_ros_namespace_conventions else 'false'),
    ]
    return [indent + line for text in lines for line in text.split('\n')]


def offered_qos_profiles_yaml(profiles):
    """Return the ``offered_qos_profiles`` channel metadata value (yaml-cpp Dump style)."""
    if not profiles:
        return '[]'
    return '\n'.join(line for p in profiles for line in qos_profile_yaml_lines(p))


def adapted_request_qos(offered_profiles):
    """
    Choose the QoS that every discovered publisher matches (rosbag2 adapt_request_to_offers).

    Reliable only if all publishers offer reliable; transient-local only if all offer it.
    Returns the profile and a warning string (or None) for a mixed set of publishers.
    """
    reliable = [p.reliability == ReliabilityPolicy.RELIABLE for p in offered_profiles]
    transient = [p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered_profiles]
    warnings = []
    if any(reliable) and not all(reliable):
        warnings.append('some but not all publishers are reliable: requesting best effort, '
                        'messages from the reliable ones may be dropped under load')
    if any(transient) and not all(transient):
        warnings.append('some but not all publishers are transient-local: requesting '
                        'volatile, earlier latched messages are not recorded')
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=SUBSCRIPTION_DEPTH,
        reliability=(ReliabilityPolicy.RELIABLE if offered_profiles and all(reliable)
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if offered_profiles and all(transient)
                    else DurabilityPolicy.VOLATILE))
    return qos, ('; '.join(warnings) or None)


def _json_value(value):
    # Non-finite floats have no JSON spelling; keep them readable rather than invalid JSON.
    def clean(item):
        if isinstance(item, float) and not math.isfinite(item):
            return repr(item)
        if isinstance(item, bytes):  # a byte-array parameter's elements
            return int.from_bytes(item, 'little')
        return item
    if isinstance(value, list):
        return json.dumps([clean(v) for v in value])
    return json.dumps(clean(value))


def sim_metadata_records(parameters):
    """Build the (name, key->string) metadata records from the sim's parameters."""
    records = [(PARAMETERS_METADATA,
                {name: _json_value(parameters[name]) for name in sorted(parameters)})]
    missing = [n for n in GEOMETRY_PARAMETERS
               if not isinstance(parameters.get(n), (int, float))
               or isinstance(parameters.get(n), bool)]
    if not missing:
        records.insert(0, (GEOMETRY_METADATA,
                           {n: repr(float(parameters[n])) for n in GEOMETRY_PARAMETERS}))
    return records, missing


def default_output_path(now=None):
    now = now or datetime.datetime.now()
    return os.path.join('runs', now.strftime('qrm_%Y%m%d_%H%M%S.mcap'))


def _yaml_string(text):
    return json.dumps(text)  # a JSON string literal is a valid YAML double-quoted scalar


def rosbag2_metadata_yaml(path, topics, start_ns, end_ns):
    """
    Build the ``serialized_metadata`` of rosbag2's ``rosbag2`` metadata record (version 9).

    ``topics`` is a list of (name, type, offered_profiles, type_hash, message_count).
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
        for topic, type_name, profiles, type_hash, messages in topics:
            lines += ['  - topic_metadata:', f'      name: {_yaml_string(topic)}',
                      f'      type: {_yaml_string(type_name)}',
                      '      serialization_format: cdr']
            if profiles:
                lines.append('      offered_qos_profiles:')
                for profile in profiles:
                    lines += qos_profile_yaml_lines(profile, ' ' * 8)
            else:
                lines.append('      offered_qos_profiles: []')
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


class McapRunFile:
    """The MCAP writer plus the chunk, fsync and error bookkeeping; no ROS in here."""

    def __init__(self, path, compression, max_chunk_duration_ns):
        folder = os.path.dirname(os.path.abspath(path))
        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as error:
            raise RecorderError(f'cannot create output {path!r}: folder {folder!r}: '
                                f'{error.strerror} (errno {error.errno})') from None
        try:
            self._stream = open(path, 'xb', buffering=1024 * 1024)
        except FileExistsError:
            raise RecorderError(f'output {path!r} already exists; refusing to overwrite it '
                                '(choose another output path)') from None
        except OSError as error:
            raise RecorderError(f'cannot create output {path!r}: {error.strerror} '
                                f'(errno {error.errno})') from None
        self.path = path
        self._max_chunk_duration_ns = max_chunk_duration_ns
        self._writer = Writer(self._stream, chunk_size=1 << 62, compression=compression)
        self._schemas = {}
        self._counts = {}
        self._channel_info = {}
        self._chunk_start_ns = None
        self._chunk_bytes = 0
        self._good_offset = 0
        self.message_count = 0
        self.message_count_on_disk = 0
        self.start_ns = None
        self.end_ns = None
        self.failed = False
        self._guard(self._writer.start, 'ros2', 'qrm_ros mcap_recorder')
        self._guard(self._commit)

    def _guard(self, operation, *args):
        try:
            return operation(*args)
        except OSError as error:
            self._abandon()
            raise RecorderError(
                f'cannot write {self.path!r}: {error.strerror or error} (errno {error.errno}); '
                f'the file keeps the {self.message_count_on_disk} messages up to its last '
                'complete chunk (read it with qrm_ros.bag_reader)') from None

    def _commit(self):
        # Everything buffered goes to the OS and the disk: a kill now loses nothing before it.
        self._writer.flush()
        os.fsync(self._stream.fileno())
        self._good_offset = self._stream.tell()
        self.message_count_on_disk = self.message_count
        self._chunk_start_ns = None
        self._chunk_bytes = 0

    def _abandon(self):
        # Cut any half-written record so the file ends on a whole record, then let go of it.
        self.failed = True
        fd = self._stream.fileno()
        try:
            os.ftruncate(fd, self._good_offset)
        except OSError:
            pass
        try:
            os.close(fd)
        except OSError:
            pass
        try:
            self._stream.close()
        except (OSError, ValueError):
            pass

    def add_channel(self, topic, type_name, offered_profiles, type_hash):
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            try:
                text = message_definition(type_name)
                schema_id = self._guard(self._writer.register_schema, type_name, 'ros2msg',
                                        text.encode('utf-8'))
            except LookupError:
                schema_id = 0
                raise
            finally:
                self._schemas[type_name] = schema_id
        metadata = {'offered_qos_profiles': offered_qos_profiles_yaml(offered_profiles),
                    'topic_type_hash': type_hash}
        channel_id = self._guard(self._writer.register_channel, topic, 'cdr', schema_id,
                                 metadata)
        self._counts[channel_id] = 0
        self._channel_info[channel_id] = (topic, type_name, list(offered_profiles), type_hash)
        return channel_id

    def add_message(self, channel_id, log_time_ns, publish_time_ns, data):
        if self._chunk_start_ns is None:
            self._chunk_start_ns = log_time_ns
        elif log_time_ns - self._chunk_start_ns >= self._max_chunk_duration_ns:
            self._guard(self._commit)
            self._chunk_start_ns = log_time_ns
        self._guard(self._writer.add_message, channel_id, log_time_ns, data, publish_time_ns)
        self._counts[channel_id] += 1
        self.message_count += 1
        if self.start_ns is None or log_time_ns < self.start_ns:
            self.start_ns = log_time_ns
        if self.end_ns is None or log_time_ns > self.end_ns:
            self.end_ns = log_time_ns
        self._chunk_bytes += len(data)
        if self._chunk_bytes >= CHUNK_SIZE_BYTES:
            self._guard(self._commit)

    def close_chunk_if_due(self, now_ns):
        if (self._chunk_start_ns is not None
                and now_ns - self._chunk_start_ns >= self._max_chunk_duration_ns):
            self._guard(self._commit)

    def add_metadata(self, name, data):
        self._guard(self._writer.add_metadata, name, data)

    def finish(self):
        topics = [info + (self._counts[cid],) for cid, info in self._channel_info.items()]
        yaml_text = rosbag2_metadata_yaml(self.path, topics, self.start_ns or 0,
                                          self.end_ns or 0)
        self._guard(self._writer.add_metadata, 'rosbag2', {'serialized_metadata': yaml_text})
        self._guard(self._writer.finish)
        self._guard(self._commit)
        self._stream.close()

    def topic_counts(self):
        return {info[0]: self._counts[cid] for cid, info in self._channel_info.items()}


def _seconds_in(name, value, low, high):
    """Return a duration parameter as float, or refuse it naming the allowed range."""
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or not low <= value <= high):
        raise RecorderError(f'parameter {name}={value!r} s is outside [{low:g}, {high:g}] s')
    return float(value)


class Recorder(Node):
    """Subscribes (serialized) to the configured topics as they appear and writes them."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        read_only = {'read_only': True}
        self.declare_parameter('output', '', ParameterDescriptor(
            description='MCAP file to write; empty = runs/qrm_<date>_<time>.mcap in the working '
                        'directory. Folders are created; an existing file is never overwritten.',
            **read_only))
        self.declare_parameter('topics', DEFAULT_TOPICS, ParameterDescriptor(
            description='Topics to record (relative names resolve in this node\'s namespace); '
                        'topics that appear later are picked up.', **read_only))
        self.declare_parameter('compression', 'zstd', ParameterDescriptor(
            description='Chunk compression: zstd, lz4 or none.', **read_only))
        self.declare_parameter('max_chunk_duration', 1.0, ParameterDescriptor(
            description='Longest span of log time per chunk (s); a kill loses at most this.',
            dynamic_typing=True, **read_only))
        self.declare_parameter('sim_node', '/shaper_sim', ParameterDescriptor(
            description='Node whose parameters (geometry and all) go into the file metadata.',
            **read_only))
        self.declare_parameter('sim_wait_timeout', 5.0, ParameterDescriptor(
            description='Time (s) to wait for the sim node\'s parameter services before warning '
                        'that the file has no geometry metadata yet (it keeps trying).',
            dynamic_typing=True, **read_only))
        self.settings = self._validated_settings()
        self.run_file = McapRunFile(self.settings['output'],
                                    COMPRESSIONS[self.settings['compression']],
                                    int(round(self.settings['max_chunk_duration'] * 1e9)))
        self.fatal_error = None
        self._wanted = {}
        for topic in self.settings['topics']:
            self._wanted[self.resolve_topic_name(topic)] = topic
        self._recorded_topics = {}
        self._requested = {}
        self._warned = set()
        self._metadata_done = False
        self._sim_started = time.monotonic()
        self._sim_warned = False
        self._pending_call = None
        sim = self.settings['sim_node'].rstrip('/')
        self._list_client = self.create_client(ListParameters, sim + '/list_parameters')
        self._get_client = self.create_client(GetParameters, sim + '/get_parameters')
        self._poll_count = 0
        self.create_timer(TOPIC_POLL_PERIOD, self._guarded(self._poll))
        chunk_check = min(0.25, max(0.001, self.settings['max_chunk_duration'] / 10.0))
        self.create_timer(chunk_check, self._guarded(self._close_chunk_if_due))
        self.get_logger().info(
            f'recording {", ".join(sorted(self._wanted))} to {self.run_file.path} '
            f'({self.settings["compression"]}, chunks of at most '
            f'{self.settings["max_chunk_duration"]} s)')
        self._poll()

    def _validated_settings(self):
        value = {name: self.get_parameter(name).value for name in
                 ('output', 'topics', 'compression', 'max_chunk_duration', 'sim_node',
                  'sim_wait_timeout')}
        if not value['output']:
            value['output'] = default_output_path()
        if value['compression'] not in COMPRESSIONS:
            raise RecorderError(f'parameter compression={value["compression"]!r} is not one of '
                                f'{", ".join(COMPRESSIONS)}')
        value['max_chunk_duration'] = _seconds_in('max_chunk_duration',
                                                  value['max_chunk_duration'],
                                                  *MAX_CHUNK_DURATION_RANGE)
        topics = value['topics']
        if (not isinstance(topics, list) or not topics
                or not all(isinstance(t, str) and t for t in topics)):
            raise RecorderError(f'parameter topics={topics!r} must be a non-empty list of topic '
                                'names')
        value['sim_wait_timeout'] = _seconds_in('sim_wait_timeout', value['sim_wait_timeout'],
                                                0.0, 3600.0)
        return value

    def _guarded(self, callback):
        def run(*args):
            if self.fatal_error is not None:
                return
            try:
                callback(*args)
            except RecorderError as error:
                self.fatal_error = str(error)
        return run

    def _close_chunk_if_due(self):
        self.run_file.close_chunk_if_due(time.time_ns())

    def _poll(self):
        self._poll_count += 1
        if len(self._recorded_topics) < len(self._wanted) or self._poll_count % 10 == 0:
            self._poll_topics()
        if not self._metadata_done:
            self._poll_sim_parameters()

    def _poll_topics(self):
        graph = dict(self.get_topic_names_and_types())
        for topic in self._wanted:
            if topic not in graph:
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if topic in self._recorded_topics:
                self._warn_on_incompatible(topic, publishers)
                continue
            if not publishers:
                continue  # nothing to adapt the QoS to yet; subscribe when one appears
            types = graph[topic]
            if len(types) != 1:
                self._warn_once(('types', topic), f'topic {topic} has several types {types}; '
                                'not recording it')
                continue
            self._subscribe(topic, types[0], publishers)

    def _warn_once(self, key, text):
        if key not in self._warned:
            self._warned.add(key)
            self.get_logger().warning(text)

    def _warn_on_incompatible(self, topic, publishers):
        requested = self._requested[topic]
        for info in publishers:
            offered = info.qos_profile
            if ((requested.reliability == ReliabilityPolicy.RELIABLE
                 and offered.reliability != ReliabilityPolicy.RELIABLE)
                    or (requested.durability == DurabilityPolicy.TRANSIENT_LOCAL
                        and offered.durability != DurabilityPolicy.TRANSIENT_LOCAL)):
                self._warn_once(('late', topic, info.node_namespace, info.node_name),
                                f'a new publisher {info.node_namespace.rstrip("/")}/'
                                f'{info.node_name} on {topic} offers QoS incompatible with the '
                                'reliable/transient-local subscription made for the earlier '
                                'publishers: its messages are not recorded')

    def _subscribe(self, topic, type_name, publishers):
        try:
            package, _, name = type_name.split('/')
            message_class = getattr(importlib.import_module(package + '.msg'), name)
        except (ValueError, ImportError, AttributeError):
            self._warn_once(('type', topic), f'cannot import message type {type_name} of '
                            f'{topic}; not recording it')
            return
        offered = [info.qos_profile for info in publishers]
        hashes = [str(info.topic_type_hash) for info in publishers]
        type_hash = next((h for h in hashes if h.startswith('RIHS')), '')
        qos, warning = adapted_request_qos(offered)
        if warning:
            self.get_logger().warning(f'{topic}: {warning}')
        try:
            channel_id = self.run_file.add_channel(topic, type_name, offered, type_hash)
        except LookupError as error:
            self.get_logger().warning(f'{topic}: {error}; recording without a schema')
            channel_id = self.run_file.add_channel(topic, type_name, offered, type_hash)
        write = self.run_file.add_message

        def on_message(data, info):
            # Two parameters exactly: rclpy passes the message info only to such callbacks.
            if self.fatal_error is not None:
                return
            received = info.get('received_timestamp') or time.time_ns()
            try:
                write(channel_id, received, info.get('source_timestamp') or received, data)
            except RecorderError as error:
                self.fatal_error = str(error)

        self._recorded_topics[topic] = self.create_subscription(
            message_class, topic, on_message, qos, raw=True)
        self._requested[topic] = qos
        self.get_logger().info(f'recording {topic} ({type_name})')

    def _poll_sim_parameters(self):
        if self._pending_call is not None:
            return
        if not (self._list_client.service_is_ready() and self._get_client.service_is_ready()):
            if (not self._sim_warned and time.monotonic() - self._sim_started
                    > self.settings['sim_wait_timeout']):
                self._sim_warned = True
                self.get_logger().warning(
                    f'no parameter services of {self.settings["sim_node"]} after '
                    f'{self.settings["sim_wait_timeout"]} s: the file has no geometry/parameter '
                    'metadata yet (they are added if the node appears later)')
            return
        request = ListParameters.Request()
        request.depth = ListParameters.Request.DEPTH_RECURSIVE
        self._pending_call = self._list_client.call_async(request)
        self._pending_call.add_done_callback(self._guarded(self._on_parameter_list))

    def _answer(self, future):
        # A failed or cancelled call (the sim went away meanwhile): try again on the next poll.
        if future.cancelled() or future.exception() is not None or future.result() is None:
            self._pending_call = None
            return None
        return future.result()

    def _on_parameter_list(self, future):
        answer = self._answer(future)
        if answer is None:
            return
        names = list(answer.result.names)
        request = GetParameters.Request()
        request.names = names
        call = self._get_client.call_async(request)
        self._pending_call = call
        call.add_done_callback(self._guarded(lambda done: self._on_parameters(names, done)))

    def _on_parameters(self, names, future):
        answer = self._answer(future)
        if answer is None:
            return
        values = answer.values
        parameters = {name: parameter_value_to_python(value)
                      for name, value in zip(names, values)}
        records, missing = sim_metadata_records(parameters)
        for name, data in records:
            self.run_file.add_metadata(name, data)
        self._metadata_done = True
        self._pending_call = None
        if missing:
            self.get_logger().warning(
                f'{self.settings["sim_node"]} lacks numeric geometry parameters {missing}: '
                f'no {GEOMETRY_METADATA} record written')
        self.get_logger().info(f'stored {len(parameters)} parameters of '
                               f'{self.settings["sim_node"]} in the file metadata')

    def finish(self):
        if not self._metadata_done:
            self.get_logger().warning(
                f'{self.settings["sim_node"]} never answered: the file has no '
                f'{GEOMETRY_METADATA} / {PARAMETERS_METADATA} metadata')
        self.run_file.finish()
        counts = self.run_file.topic_counts()
        self.get_logger().info(
            f'wrote {self.run_file.message_count} messages to {self.run_file.path}: '
            + ', '.join(f'{topic} {count}' for topic, count in sorted(counts.items())))


def main(args=None):
    stop = []

    def request_stop(signum, frame):
        stop.append(signum)

    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    previous = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    recorder = None
    exit_code = 0
    try:
        recorder = Recorder()
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(recorder)
        while not stop and recorder.fatal_error is None:
            executor.spin_once(timeout_sec=0.1)
        # Take what DDS already delivered before closing: spin until it stays idle briefly.
        idle, deadline = 0, time.monotonic() + 1.0
        while recorder.fatal_error is None and idle < 3 and time.monotonic() < deadline:
            before = recorder.run_file.message_count
            executor.spin_once(timeout_sec=0.01)
            idle = idle + 1 if recorder.run_file.message_count == before else 0
        if recorder.fatal_error is not None:
            raise RecorderError(recorder.fatal_error)
        recorder.finish()
    except (RecorderError, ParameterException, NameValidationException) as error:
        print(f'{NODE_NAME}: error: {error}', file=sys.stderr, flush=True)
        exit_code = 1
    finally:
        if recorder is not None:
            recorder.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        for number, handler in previous.items():
            signal.signal(number, handler)
    return exit_code


if __name__ == '__main__':
    sys.exit(main())
