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
The graph's topics as Foxglove channels: ``cdr`` messages with their ``ros2msg`` schema.

Each topic the bridge serves becomes a channel whose schema is the type's full definition
text, as rosbag2 and the recorder write it (``rosbag2_formats.find_message_definition``), and
whose messages are the serialized bytes DDS delivered (a raw subscription: nothing decoded or
re-encoded). A topic is subscribed on ROS only while a client subscribes to its channel, so a
latched topic (``/robot_description``) reaches the client when it subscribes, and an idle
bridge costs nothing per message. Topics that appear are advertised at the next look at the
graph, vanished ones removed.

The messages are handed to the SDK in batches, every ``send_period`` seconds (``SendBatch``):
the SDK's server wakes its sending thread for each message it is given while idle, and at
1 kHz those wake-ups were most of the bridge's CPU (61 us per message one at a time, 20 us in
fives, 8 us in twenties, serving one client); each keeps the time it arrived as its log time.

The server reports client subscriptions on its own threads (``client_subscribed``,
``client_unsubscribed``); ROS entities are made and destroyed only on the executor's thread
(``update``, ``reconcile``).
"""

import importlib
import threading
import time
from typing import Callable, Dict, Iterable, List, Optional, Set, Tuple

from foxglove import Channel, Context, Schema
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.subscription import Subscription

from qrm_ros.node.recorder.recorder import adapted_request_qos
from qrm_ros.recording.rosbag2_formats import find_message_definition

__all__ = ['CDR', 'ROS2MSG', 'SendBatch', 'TopicChannels', 'message_class']

CDR = 'cdr'
ROS2MSG = 'ros2msg'


def message_class(type_name: str):
    """Return the class of 'pkg/msg/Type' (or 'pkg/Type'); LookupError if it cannot load."""
    parts = type_name.split('/')
    if len(parts) == 2:
        parts.insert(1, 'msg')
    if len(parts) != 3 or not all(parts):
        raise LookupError(f'type name {type_name!r} is not pkg/msg/Type')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError):
        raise LookupError(f'cannot import {type_name}') from None


class SendBatch:
    """
    Messages gathered as they arrive and handed to the SDK together, every period (s).

    Gathering and sending both run on the executor's thread (a steady timer, so a paused
    simulated clock holds nothing back); period 0 hands each message over as it arrives.
    """

    def __init__(self, node: Node, period: float):
        self.period = period
        self._pending: List[Tuple[Callable[..., None], bytes, int]] = []
        if period > 0:
            node.create_timer(period, self.send, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def forwarder(self, log: Callable[..., None]) -> Callable[[bytes], None]:
        """Return the subscription callback for a channel whose log is `log`."""
        if self.period <= 0:
            return log
        append, now = self._pending.append, time.time_ns

        def gather(data: bytes) -> None:
            append((log, data, now()))
        return gather

    def send(self) -> None:
        """Hand the gathered messages to the SDK, in the order they came."""
        if not self._pending:
            return
        batch = list(self._pending)
        self._pending.clear()
        for log, data, log_time in batch:
            log(data, log_time=log_time)


class _Served:
    """One served topic: its type, channel and (while a client wants it) subscription."""

    def __init__(self, type_name: str, channel: Channel):
        self.type_name = type_name
        self.channel = channel
        self.subscription: Optional[Subscription] = None


class TopicChannels:
    """The channels of the served topics, and their ROS subscriptions while wanted."""

    def __init__(self, node: Node, context: Context, wanted: Optional[Iterable[str]],
                 warn: Callable[[str], None], send_period: float = 0.0):
        self._node = node
        self._batch = SendBatch(node, send_period)
        self._context = context
        self._wanted = None if wanted is None else {node.resolve_topic_name(t) for t in wanted}
        self._warn = warn
        self._warned: Set[Tuple[str, str]] = set()
        self._served: Dict[str, _Served] = {}
        self._lock = threading.Lock()
        self._subscribers: Dict[int, Set[int]] = {}  # channel id -> client ids
        self.changed = threading.Event()  # a client (un)subscribed: reconcile soon
        self.reserved: Set[str] = set()  # topics the bridge serves itself, not from ROS

    def _warn_once(self, topic: str, text: str) -> None:
        if (topic, text) not in self._warned:
            self._warned.add((topic, text))
            self._warn(text)

    @property
    def topics(self) -> Dict[str, str]:
        """Served topic -> type name."""
        return {topic: served.type_name for topic, served in self._served.items()}

    def channel_id(self, topic: str) -> Optional[int]:
        served = self._served.get(topic)
        return None if served is None else served.channel.id()

    def update(self, graph: Dict[str, List[str]], publishers: Callable[[str], list]) -> None:
        """Advertise the topics with a foreign publisher, remove the rest (executor thread)."""
        present = {}
        for topic, types in graph.items():
            if (self._wanted is not None and topic not in self._wanted) or topic in self.reserved:
                continue
            if not publishers(topic):
                continue
            if len(types) != 1:
                self._warn_once(topic, f'topic {topic} has several types {types}: not served')
                continue
            present[topic] = types[0]
        for topic in [t for t, s in self._served.items() if present.get(t) != s.type_name]:
            self._remove(topic)
        for topic in sorted(set(present) - set(self._served)):
            self._add(topic, present[topic])

    def _add(self, topic: str, type_name: str) -> None:
        definition, problem = find_message_definition(type_name)
        if definition is None:
            self._warn_once(topic, f'topic {topic}: {problem}; not served')
            return
        schema = Schema(name=type_name, encoding=ROS2MSG, data=definition.encode())
        channel = Channel(topic, schema=schema, message_encoding=CDR, context=self._context)
        self._served[topic] = _Served(type_name, channel)
        self._node.get_logger().info(f'serving {topic} ({type_name})')

    def _remove(self, topic: str) -> None:
        served = self._served.pop(topic)
        if served.subscription is not None:
            self._node.destroy_subscription(served.subscription)
        served.channel.close()  # unadvertised; the server unsubscribes its clients
        with self._lock:
            self._subscribers.pop(served.channel.id(), None)
        self._node.get_logger().info(f'{topic} is gone: removed')

    def subscriber_count(self, channel_id: int) -> int:
        with self._lock:
            return len(self._subscribers.get(channel_id, ()))

    def reserve(self, topics: Set[str]) -> None:
        """Serve these topics from the bridge itself: never from ROS (executor thread)."""
        self.reserved |= topics
        for topic in [t for t in self._served if t in topics]:
            self._remove(topic)

    def client_subscribed(self, client_id: int, channel_id: int) -> None:
        with self._lock:
            self._subscribers.setdefault(channel_id, set()).add(client_id)
        self.changed.set()

    def client_unsubscribed(self, client_id: int, channel_id: int) -> None:
        with self._lock:
            self._subscribers.get(channel_id, set()).discard(client_id)
        self.changed.set()

    def reconcile(self, publishers_of: Callable[[str], list]) -> None:
        """Subscribe the channels clients want, unsubscribe the rest (executor thread)."""
        self.changed.clear()
        with self._lock:
            wanted = {channel_id for channel_id, clients in self._subscribers.items() if clients}
        for topic, served in self._served.items():
            want = served.channel.id() in wanted
            if want and served.subscription is None:
                served.subscription = self._subscribe(topic, served, publishers_of(topic))
            elif not want and served.subscription is not None:
                self._node.destroy_subscription(served.subscription)
                served.subscription = None

    def _subscribe(self, topic: str, served: _Served, publishers: list):
        try:
            kind = message_class(served.type_name)
        except LookupError as error:
            self._warn_once(topic, f'topic {topic}: {error}; not forwarded')
            return None
        qos, warning = adapted_request_qos([info.qos_profile for info in publishers])
        if warning:
            self._warn_once(topic, f'{topic}: {warning}')
        log = served.channel.base.log  # the bytes as they are, without Channel.log's checks
        return self._node.create_subscription(kind, topic, self._batch.forwarder(log), qos,
                                              raw=True)
