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
The graph's services as Foxglove services, and client publishing as ROS publishers.

A service call arrives as CDR bytes of the request: rclpy's own serialization reads it into
the request type, the ROS service is called, and its response goes back serialized. Parameter
services (``rcl_interfaces``) and type-description services are left to the parameters
capability and out of the list. A client that advertises a channel with ``cdr`` encoding and
a message schema name publishes on that ROS topic; each message is checked by deserializing
it before it is published, so a malformed one reaches no node and gets an error status.

Server callbacks run on the server's threads; ROS clients and publishers are made and
destroyed on the executor's thread (``update``, ``make_publishers``).
"""

import threading
from typing import Callable, Dict, List, Optional, Tuple

from foxglove import MessageSchema, Schema, Service, ServiceRequest, ServiceSchema
from rclpy.client import Client
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.serialization import deserialize_message, serialize_message

from qrm_ros.node.bridge.bridge_topics import CDR, message_class, ROS2MSG
from qrm_ros.node.process.ros_process import rcl_error_text, RCLError
from qrm_ros.recording.rosbag2_formats import find_service_definitions

__all__ = ['ClientPublishers', 'PublishRefusal', 'SERVICE_CALL_TIMEOUT', 'ServiceBridge',
           'call_from_thread', 'service_class']

SERVICE_CALL_TIMEOUT = 5.0  # s, for the answer of a bridged ROS service
# Service packages the bridge leaves out (parameters have their own capability).
HIDDEN_SERVICE_PACKAGES = ('rcl_interfaces', 'type_description_interfaces')
PUBLISHER_DEPTH = 10
PUBLISHER_WAIT = 1.0  # s, a client's first message waits at most this for its publisher


class PublishRefusal(ValueError):
    """A client channel or message the bridge does not publish; the text says why."""


def service_class(type_name: str):
    """Return the Python class of 'pkg/srv/Type'; LookupError if it cannot load."""
    package, kind, name = (type_name.split('/') + ['', ''])[:3]
    if kind != 'srv':
        raise LookupError(f'service type name {type_name!r} is not pkg/srv/Type')
    try:
        return message_class(f'{package}/srv/{name}')
    except LookupError:
        raise LookupError(f'cannot import {type_name}') from None


class ServiceBridge:
    """Advertise the graph's services on the server and call them for its clients."""

    def __init__(self, node: Node, add: Callable[[List[Service]], None],
                 remove: Callable[[List[str]], None], warn: Callable[[str], None]):
        self._node = node
        self._add, self._remove, self._warn = add, remove, warn
        self._clients: Dict[str, Tuple[str, Client]] = {}  # name -> (type, rclpy client)
        self._warned: set = set()

    @property
    def services(self) -> Dict[str, str]:
        return {name: type_name for name, (type_name, client) in self._clients.items()}

    def update(self, graph: Dict[str, List[str]]) -> None:
        """Advertise new services and remove vanished ones (executor thread)."""
        present = {name: types[0] for name, types in graph.items()
                   if len(types) == 1 and types[0].split('/')[0] not in HIDDEN_SERVICE_PACKAGES}
        gone = [name for name, (type_name, _) in self._clients.items()
                if present.get(name) != type_name]
        if gone:
            self._remove(gone)
            for name in gone:
                self._node.destroy_client(self._clients.pop(name)[1])
        made = [self._service(name, present[name]) for name in sorted(present)
                if name not in self._clients]
        new = [service for service in made if service is not None]
        if new:
            self._add(new)

    def _service(self, name: str, type_name: str) -> Optional[Service]:
        try:
            kind = service_class(type_name)
        except LookupError as error:
            self._refuse(name, str(error))
            return None
        texts, problem = find_service_definitions(type_name)
        if texts is None:
            self._refuse(name, problem or 'no definition')
            return None
        schema = ServiceSchema(type_name, **{
            part: MessageSchema(encoding=CDR, schema=Schema(
                name=f'{type_name}_{part.capitalize()}', encoding=ROS2MSG, data=text.encode()))
            for part, text in zip(('request', 'response'), texts)})
        client = self._node.create_client(kind, name)
        self._clients[name] = (type_name, client)
        self._node.get_logger().info(f'serving service {name} ({type_name})')
        return Service(name, schema=schema, handler=lambda call: self._call(kind, client, call))

    def _refuse(self, name: str, why: str) -> None:
        if name not in self._warned:
            self._warned.add(name)
            self._warn(f'service {name}: {why}; not served')

    def _call(self, kind, client, call: ServiceRequest) -> bytes:
        """Serve one call on a server thread; an exception's text goes back as the failure."""
        if call.encoding != CDR:
            raise ValueError(f'request encoding {call.encoding!r}: only {CDR} is accepted')
        try:
            request = deserialize_message(call.payload, kind.Request)
        except Exception as error:  # rclpy raises several kinds on bytes that are not CDR
            raise ValueError(f'the request is not a CDR {kind.__name__} request: '
                             f'{rcl_error_text(error)}') from None
        return serialize_message(call_from_thread(client, request, SERVICE_CALL_TIMEOUT))


class _ClientChannel:
    def __init__(self, topic: str, kind):
        self.topic, self.kind = topic, kind
        self.publisher: Optional[Publisher] = None
        self.ready = threading.Event()


class ClientPublishers:
    """Client channels -> ROS publishers; each message checked before it is published."""

    def __init__(self, node: Node, topic_types: Callable[[str], List[str]]):
        self._node = node
        self._topic_types = topic_types
        self._lock = threading.Lock()
        self._channels: Dict[Tuple[int, int], _ClientChannel] = {}
        self._unused: List = []  # publishers to destroy on the executor's thread
        self.changed = threading.Event()

    def advertise(self, client_id: int, channel_id: int, topic: str, encoding: str,
                  schema_name: str) -> None:
        """Accept a client channel (server thread); PublishRefusal says why not."""
        if encoding != CDR:
            raise PublishRefusal(f'client channel {topic}: encoding {encoding!r}, only {CDR} '
                                 'is published')
        try:
            kind = message_class(schema_name)
        except LookupError as error:
            raise PublishRefusal(f'client channel {topic}: {error}') from None
        try:
            resolved = self._node.resolve_topic_name(topic)
        except Exception as error:  # rclpy raises several kinds on a name it cannot take
            raise PublishRefusal(f'client channel {topic!r}: not a valid ROS topic name '
                                 f'({rcl_error_text(error)})') from None
        existing = self._topic_types(resolved)
        wanted = f'{kind.__module__.split(".")[0]}/msg/{kind.__name__}'
        if existing and existing != [wanted]:
            raise PublishRefusal(f'client channel {topic}: type {schema_name} but the topic '
                                 f'has {", ".join(existing)}')
        with self._lock:
            self._channels[(client_id, channel_id)] = _ClientChannel(resolved, kind)
        self.changed.set()

    def unadvertise(self, client_id: int, channel_id: int) -> None:
        with self._lock:
            channel = self._channels.pop((client_id, channel_id), None)
            if channel is not None and channel.publisher is not None:
                self._unused.append(channel.publisher)
        self.changed.set()

    def make_publishers(self) -> None:
        """Make the publishers of new client channels, destroy unused ones (executor thread)."""
        self.changed.clear()
        with self._lock:
            unused, self._unused = self._unused, []
            new = [c for c in self._channels.values() if c.publisher is None]
        for publisher in unused:
            self._node.destroy_publisher(publisher)
        for channel in new:
            channel.publisher = self._node.create_publisher(channel.kind, channel.topic,
                                                            PUBLISHER_DEPTH)
            channel.ready.set()

    def publish(self, client_id: int, channel_id: int, data: bytes) -> None:
        """Publish a client's message (server thread); PublishRefusal if malformed."""
        with self._lock:
            channel = self._channels.get((client_id, channel_id))
        if channel is None:
            raise PublishRefusal(f'client channel {channel_id} is not accepted for publishing')
        try:
            deserialize_message(data, channel.kind)
        except Exception as error:  # rclpy raises several kinds on bytes that are not CDR
            raise PublishRefusal(f'{channel.topic}: a {len(data)}-byte message that is not a '
                                 f'CDR {channel.kind.__name__}: {rcl_error_text(error)}'
                                 ) from None
        if not channel.ready.wait(PUBLISHER_WAIT) or channel.publisher is None:
            raise PublishRefusal(f'{channel.topic}: no publisher yet, message dropped')
        try:
            channel.publisher.publish(bytes(data))
        except RCLError as error:  # bytes that read as the type but do not fit it (trailing)
            raise PublishRefusal(f'{channel.topic}: DDS refused a {len(data)}-byte '
                                 f'{channel.kind.__name__} ({rcl_error_text(error)}); '
                                 'message dropped') from None


def call_from_thread(client: Client, request, timeout: float,
                     error: Callable[[str], Exception] = RuntimeError):
    """
    Call a service from a thread other than the executor's and wait for its answer.

    The server's callbacks run on the SDK's threads while the executor spins the node
    elsewhere; a service that is missing or silent for timeout seconds raises error.
    """
    if not client.service_is_ready():
        raise error(f'{client.service_name} is not available')
    done = threading.Event()
    future = client.call_async(request)
    future.add_done_callback(lambda finished: done.set())
    if not done.wait(timeout) or future.result() is None:
        client.remove_pending_request(future)
        raise error(f'{client.service_name} did not answer in {timeout:g} s')
    return future.result()
