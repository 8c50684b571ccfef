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
Foxglove and the ``rosbags`` library open it unchanged (the text formats are in
``rosbag2_formats``, the file itself in ``mcap_run_file``). On top of that the run is made
self-describing with two metadata records read from the sim node's parameter services:
``qrm_ros.geometry`` (the five geometry parameters, ``repr(float)`` strings) and
``qrm_ros.parameters`` (every parameter, JSON-encoded). With the geometry it also writes the
machine beside the joint states (``machine_channels``): the URDF on ``/robot_description``
and the links' transforms on ``/tf_static`` and ``/tf``, so a viewer draws it moving.

Run it with the ``mcap_recorder`` command (qrm_ros.cli.mcap_recorder), which also finishes a
file left unfinished.
"""

import datetime
import importlib
import json
import math
import os
import time

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.client import Client
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from qrm_ros.core.kinematics.geometry import Geometry, KinematicsError
from qrm_ros.recording.machine_channels import MachineChannels
from qrm_ros.recording.typestore import preload_typestore
from qrm_ros.recording.mcap_run_file import COMPRESSIONS, ConfigurationError, McapRunFile
from qrm_ros.core.common.names import (DIAGNOSTICS_TOPIC, GEOMETRY_METADATA, JOINT_STATE_TYPE,
                                       JOINT_STATES_TOPIC, PARAMETER_EVENTS_TOPIC,
                                       PARAMETERS_METADATA, RAM_TWIST_TOPIC, RECORDER_NODE_NAME,
                                       SPEED_COMMAND_TOPIC)
from qrm_ros.node.process.ros_process import (MESSAGE_INFO_SIGNATURE, message_and_info,
                                              rcl_error_text, RCLError)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

DEFAULT_TOPICS = [JOINT_STATES_TOPIC, RAM_TWIST_TOPIC, SPEED_COMMAND_TOPIC, DIAGNOSTICS_TOPIC,
                  PARAMETER_EVENTS_TOPIC]
GEOMETRY_PARAMETERS = list(Geometry.field_names())
MAX_CHUNK_DURATION_RANGE = (0.001, 3600.0)
SIM_WAIT_TIMEOUT_RANGE = (0.0, 3600.0)
# Deep reader queue: a Python callback can lag a 1 kHz burst; KEEP_LAST 10 would drop then.
SUBSCRIPTION_DEPTH = 1000
TOPIC_POLL_PERIOD = 0.1
# After a stop request, take what DDS already delivered: spin until idle this many times...
DRAIN_IDLE_SPINS = 3
DRAIN_SPIN_TIMEOUT = 0.01  # s, each
DRAIN_LIMIT = 1.0  # s, at most


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


class SettingsError(ConfigurationError):
    """A parameter of the recorder outside what it accepts."""


def _seconds_in(name, value, low, high):
    """Return a duration parameter as float, or refuse it naming the allowed range."""
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or not low <= value <= high):
        raise SettingsError(f'parameter {name}={value!r} s is outside [{low:g}, {high:g}] s')
    return float(value)


class Recorder(Node):
    """Subscribes (serialized) to the configured topics as they appear and writes them."""

    def __init__(self, **kwargs):
        super().__init__(RECORDER_NODE_NAME, **kwargs)
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
        chunk_duration_ns = round(self.settings['max_chunk_duration'] * NANOSECONDS_PER_SECOND)
        self.run_file = McapRunFile(self.settings['output'],
                                    COMPRESSIONS[self.settings['compression']], chunk_duration_ns)
        self.machine = MachineChannels(self.run_file)
        preload_typestore()
        self._wanted = self.settings['wanted']  # resolved name -> as given
        self._recorded_topics = {}
        self._requested = {}
        self._warned = set()
        self._metadata_done = False
        self._sim_started = time.monotonic()
        self._sim_warned = False
        self._sim_call = None
        self._sim_parameters = AsyncParameterClient(self, self.settings['sim_node'].rstrip('/'))
        self._poll_count = 0
        self.create_timer(TOPIC_POLL_PERIOD, self._poll)
        chunk_check = min(0.25, max(0.001, self.settings['max_chunk_duration'] / 10.0))
        self.create_timer(chunk_check, self._close_chunk_if_due)
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
            raise SettingsError(f'parameter compression={value["compression"]!r} is not one of '
                                f'{", ".join(COMPRESSIONS)}')
        value['max_chunk_duration'] = _seconds_in('max_chunk_duration',
                                                  value['max_chunk_duration'],
                                                  *MAX_CHUNK_DURATION_RANGE)
        topics = value['topics']
        if (not isinstance(topics, list) or not topics
                or not all(isinstance(t, str) and t for t in topics)):
            raise SettingsError(f'parameter topics={topics!r} must be a non-empty list of topic '
                                'names')
        value['wanted'] = {}
        for topic in topics:
            try:
                value['wanted'][self.resolve_topic_name(topic)] = topic
            except RCLError as error:  # a regular expression, a space: no ROS name at all
                raise SettingsError(f'parameter topics: {topic!r} is not a ROS topic name '
                                    f'({rcl_error_text(error)}); topics are names, not '
                                    'patterns') from None
        value['sim_wait_timeout'] = _seconds_in('sim_wait_timeout', value['sim_wait_timeout'],
                                                *SIM_WAIT_TIMEOUT_RANGE)
        return value

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
        problem = self.run_file.add_schema(type_name)
        if problem:
            self.get_logger().warning(f'{topic}: {problem}; recording without a schema')
        channel_id = self.run_file.add_channel(topic, type_name, offered, type_hash)
        write = self.run_file.add_message
        joint_states = (type_name == JOINT_STATE_TYPE
                        and topic == self.resolve_topic_name(JOINT_STATES_TOPIC))
        machine = self.machine.joint_state

        def on_message(*arguments):
            data, info = message_and_info(arguments)  # either executor (ros_process)
            received = info.get('received_timestamp') or time.time_ns()
            sent = info.get('source_timestamp') or received
            write(channel_id, received, sent, data)
            if joint_states:
                machine(received, sent, data)
        on_message.__signature__ = MESSAGE_INFO_SIGNATURE  # so that rclpy passes the info

        self._recorded_topics[topic] = self.create_subscription(
            message_class, topic, on_message, qos, raw=True)
        self._requested[topic] = qos
        self.get_logger().info(f'recording {topic} ({type_name})')

    def _poll_sim_parameters(self):
        if self._sim_call is not None:
            return
        if not self._sim_parameters.services_are_ready():
            if (not self._sim_warned and time.monotonic() - self._sim_started
                    > self.settings['sim_wait_timeout']):
                self._sim_warned = True
                self.get_logger().warning(
                    f'no parameter services of {self.settings["sim_node"]} after '
                    f'{self.settings["sim_wait_timeout"]} s: the file has no geometry/parameter '
                    'metadata yet (they are added if the node appears later)')
            return
        self._sim_call = self._sim_parameters.list_parameters(callback=self._on_parameter_list)

    def _answer(self, future):
        """Return the answer of a parameter call, or None to ask again on the next poll."""
        if future.cancelled() or future.exception() is not None or future.result() is None:
            self._sim_call = None  # the sim went away meanwhile
            return None
        return future.result()

    def _on_parameter_list(self, future):
        answer = self._answer(future)
        if answer is not None:
            names = list(answer.result.names)
            self._sim_call = self._sim_parameters.get_parameters(
                names, callback=lambda done: self._on_parameters(names, done))

    def _on_parameters(self, names, future):
        answer = self._answer(future)
        if answer is None:
            return
        parameters = {name: parameter_value_to_python(value)
                      for name, value in zip(names, answer.values)}
        records, missing = sim_metadata_records(parameters)
        for name, data in records:
            self.run_file.add_metadata(name, data)
        self._metadata_done = True
        if not missing:
            self._start_machine(parameters)
        self._release_sim_parameter_clients()
        if missing:
            self.get_logger().warning(
                f'{self.settings["sim_node"]} lacks numeric geometry parameters {missing}: '
                f'no {GEOMETRY_METADATA} record written')
        self.get_logger().info(f'stored {len(parameters)} parameters of '
                               f'{self.settings["sim_node"]} in the file metadata')

    def _start_machine(self, parameters):
        try:
            geometry = Geometry(**{name: float(parameters[name]) for name in GEOMETRY_PARAMETERS})
        except (KinematicsError, ValueError) as error:
            self.get_logger().warning(f'the sim\'s geometry is not a mechanism ({error}): no '
                                      'URDF or transforms are recorded')
            return
        self.machine.start(geometry, time.time_ns())
        self.get_logger().info('recording the machine: its URDF and its links\' transforms')

    def _release_sim_parameter_clients(self):
        # AsyncParameterClient has no destroy(): its six service clients would stay in every
        # wait set the executor builds, at each of the thousands of wake-ups a second.
        for client in [c for c in vars(self._sim_parameters).values() if isinstance(c, Client)]:
            self.destroy_client(client)
        self._sim_parameters = None

    def drain(self, executor):
        """Take what DDS already delivered: spin until idle a few times (at most a second)."""
        idle, deadline = 0, time.monotonic() + DRAIN_LIMIT
        while idle < DRAIN_IDLE_SPINS and time.monotonic() < deadline:
            before = self.run_file.message_count
            executor.spin_once(timeout_sec=DRAIN_SPIN_TIMEOUT)
            idle = idle + 1 if self.run_file.message_count == before else 0

    def finish(self):
        if self.machine.started and self.machine.dropped:
            self.get_logger().warning(f'{self.machine.dropped} joint states have no transforms '
                                      '(undecodable, a joint missing or not finite, or recorded '
                                      'long before the geometry was known)')
        if not self._metadata_done:
            self.get_logger().warning(
                f'{self.settings["sim_node"]} never answered: the file has no '
                f'{GEOMETRY_METADATA} / {PARAMETERS_METADATA} metadata')
        self.run_file.finish()
        counts = self.run_file.topic_counts()
        self.get_logger().info(
            f'wrote {self.run_file.message_count} messages to {self.run_file.path}: '
            + ', '.join(f'{topic} {count}' for topic, count in sorted(counts.items())))
