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
The ``qrm_bridge`` node: the ROS 2 graph served to the Foxglove app over its WebSocket protocol.

The server is Foxglove's own SDK (``foxglove-sdk``), so the protocol is theirs end to end;
this module only maps the graph onto it:

- topics -> channels of ``cdr`` messages with ``ros2msg`` schemas, raw bytes forwarded
  (``bridge_topics``);
- the nodes' parameter services -> the parameters capability (``bridge_parameters``);
- services -> the services capability, client channels -> ROS publishers
  (``bridge_services``);
- ``package://`` URIs -> assets read from the package's share folder (the URDF);
- the machine's URDF and link transforms, when nothing in the graph publishes them
  (``bridge_machine``);
- slow clients: the SDK keeps one bounded queue per client and drops that client's oldest
  messages when it is full (the others and the graph are never held up); the bridge counts
  the SDK's notices of it per client (``bridge_clients``) and says them in the log, to the
  clients' status and in the ``qrm_bridge: clients`` status on /diagnostics (once a second).
"""

import logging
import os
from typing import Dict, List, Optional, Sequence

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from diagnostic_msgs.msg import DiagnosticArray
import foxglove
from foxglove import Context, Parameter, StatusLevel
from foxglove.websocket import Capability, ChannelView, Client, ClientChannel, ServerListener
from rcl_interfaces.msg import ParameterEvent
from rclpy.node import Node
from std_msgs.msg import Header

from qrm_ros.node.bridge.bridge_clients import ClientBook, clients_status
from qrm_ros.node.bridge.bridge_machine import MACHINE_TOPICS, MachineView
from qrm_ros.node.bridge.bridge_parameters import from_ros, NODE_SEPARATOR, ParameterBridge
from qrm_ros.node.bridge.bridge_services import ClientPublishers, PublishRefusal, ServiceBridge
from qrm_ros.node.bridge.bridge_topics import CDR, TopicChannels
from qrm_ros.core.common.names import (absolute_topic, BRIDGE_DEFAULT_PORT, BRIDGE_NODE_NAME,
                                       DIAGNOSTICS_TOPIC, PARAMETER_EVENTS_TOPIC)

__all__ = ['BridgeNode', 'BridgeSettings', 'DEFAULT_ADDRESS',
           'DEFAULT_CLIENT_QUEUE', 'DEFAULT_PORT', 'DEFAULT_SEND_PERIOD', 'package_asset']

DEFAULT_ADDRESS = '127.0.0.1'  # loopback: nothing outside this machine reaches the bridge
DEFAULT_PORT = BRIDGE_DEFAULT_PORT
DEFAULT_CLIENT_QUEUE = 1024  # messages per client before its oldest are dropped
DEFAULT_SEND_PERIOD = 0.01  # s between two hand-overs of the gathered messages to the server
TICK_PERIOD = 0.05  # s, how soon a client's subscription or advertisement takes effect
GRAPH_TICKS = 10  # ticks between looks at the graph (0.5 s)
STATUS_TICKS = 20  # ticks between two clients statuses on /diagnostics (1 s)
PACKAGE_SCHEME = 'package://'
SDK_LOGGER = 'foxglove'  # the SDK logs through Python's logging under this name


def _status_id(client_address: str) -> str:
    return f'{BRIDGE_NODE_NAME} client {client_address}'


class BridgeSettings:
    """Where to listen, what to serve, how many messages a client may fall behind."""

    def __init__(self, address: str = DEFAULT_ADDRESS, port: int = DEFAULT_PORT,
                 topics: Optional[Sequence[str]] = None,
                 client_queue: int = DEFAULT_CLIENT_QUEUE,
                 send_period: float = DEFAULT_SEND_PERIOD):
        self.address, self.port, self.client_queue = address, port, client_queue
        self.send_period = send_period
        self.topics = None if not topics else list(topics)


def package_asset(uri: str) -> Optional[bytes]:
    """Return the file a ``package://pkg/path`` URI names in pkg's share folder, or None."""
    if not uri.startswith(PACKAGE_SCHEME):
        return None
    package, _, relative = uri[len(PACKAGE_SCHEME):].partition('/')
    try:
        share = os.path.realpath(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError):
        return None
    path = os.path.realpath(os.path.join(share, relative))
    if os.path.commonpath([share, path]) != share or not os.path.isfile(path):
        return None  # nothing outside the share folder is served
    with open(path, 'rb') as handle:
        return handle.read()


class _SdkLog(logging.Handler):
    """The SDK's log into the node's: its warnings and errors; its client notices counted."""

    def __init__(self, bridge: 'BridgeNode'):
        super().__init__(logging.INFO)
        self._bridge = bridge

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if self._bridge.client_book.read(text):
            return
        if record.levelno >= logging.WARNING:
            self._bridge.get_logger().warning(f'server: {text}')


class _Listener(ServerListener):
    """The server's callbacks (on its threads), handed to the bridge's parts."""

    def __init__(self, bridge: 'BridgeNode'):
        self._bridge = bridge

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self._bridge.topic_channels.client_subscribed(client.id, channel.id)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self._bridge.topic_channels.client_unsubscribed(client.id, channel.id)

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        try:
            self._bridge.client_publishers.advertise(client.id, channel.id, channel.topic,
                                                     channel.encoding, channel.schema_name)
        except PublishRefusal as refusal:
            self._bridge.report(f'client {client.id}: {refusal}', StatusLevel.Error)

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        self._bridge.client_publishers.unadvertise(client.id, client_channel_id)

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        try:
            self._bridge.client_publishers.publish(client.id, client_channel_id, data)
        except PublishRefusal as refusal:
            self._bridge.report(f'client {client.id}: {refusal}', StatusLevel.Error)

    def on_get_parameters(self, client: Client, param_names: List[str],
                          request_id: Optional[str] = None) -> List[Parameter]:
        return self._bridge.parameters.get(param_names)

    def on_set_parameters(self, client: Client, parameters: List[Parameter],
                          request_id: Optional[str] = None) -> List[Parameter]:
        return self._bridge.parameters.set(parameters)

    def on_parameters_subscribe(self, param_names: List[str]) -> None:
        return None

    def on_parameters_unsubscribe(self, param_names: List[str]) -> None:
        return None


class BridgeNode(Node):
    """Joins the graph and serves it on a Foxglove WebSocket server until closed."""

    def __init__(self, settings: BridgeSettings, **kwargs):
        super().__init__(BRIDGE_NODE_NAME, **kwargs)
        self.settings = settings
        self.client_book = ClientBook()  # client address -> the SDK's notices (any thread)
        self._said_clients: Dict[str, bool] = {}  # address -> connected, as last said
        self._foxglove_context = Context()
        self.topic_channels = TopicChannels(self, self._foxglove_context, settings.topics,
                                            self.get_logger().warning, settings.send_period)
        self.parameters = ParameterBridge(self, lambda text: self.report(text))
        self.client_publishers = ClientPublishers(self, self._topic_types)
        self._sdk_log = _SdkLog(self)
        sdk_logger = logging.getLogger(SDK_LOGGER)
        sdk_logger.addHandler(self._sdk_log)
        sdk_logger.setLevel(logging.INFO)
        sdk_logger.propagate = False  # only through the node's log
        foxglove.set_log_level(logging.INFO)
        self.server = foxglove.start_server(
            name=BRIDGE_NODE_NAME, host=settings.address, port=settings.port,
            capabilities=[Capability.ClientPublish, Capability.Parameters, Capability.Services],
            server_listener=_Listener(self), supported_encodings=[CDR],
            asset_handler=package_asset, context=self._foxglove_context,
            message_backlog_size=settings.client_queue)
        self.service_bridge = ServiceBridge(self, self.server.add_services,
                                            self.server.remove_services,
                                            self.get_logger().warning)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        self.create_subscription(ParameterEvent, PARAMETER_EVENTS_TOPIC,
                                 self._on_parameter_event, 100)
        # The machine's URDF and transforms: served unless --topics leaves them out.
        self.machine = MachineView(self, self._foxglove_context, self.parameters,
                                   self.topic_channels.subscriber_count,
                                   self.topic_channels.reserve) if (
            settings.topics is None or set(MACHINE_TOPICS) & {
                absolute_topic(topic) for topic in settings.topics}) else None
        self._ticks = 0
        self.create_timer(TICK_PERIOD, self._tick)
        self._look_at_graph()

    @property
    def address(self) -> str:
        """The ws:// address clients connect to."""
        host = self.settings.address
        return f'ws://{"[" + host + "]" if ":" in host else host}:{self.server.port}'

    def report(self, text: str, level: StatusLevel = StatusLevel.Warning) -> None:
        """Say it in the log and to the clients (their status / problems list)."""
        self.get_logger().warning(text)
        self.server.publish_status(text, level)

    @property
    def slow_client_notices(self) -> Dict[str, int]:
        """Client address -> the SDK's full-queue notices for it (gone clients included)."""
        return {a: n for a, n in self.client_book.notices().items() if n}

    def _say_clients(self) -> None:
        """Say the SDK's notices (on the executor's thread, not inside the SDK's send)."""
        notices = self.client_book.notices()
        for address in self.client_book.take_pending():
            count = notices.get(address, 0)
            text = (f'client {address} falls behind: its oldest messages are dropped (queue of '
                    f'{self.settings.client_queue} messages per client; {count} full-queue '
                    f'notice{"s" if count != 1 else ""} so far)')
            self.get_logger().warning(text)
            self.server.publish_status(text, StatusLevel.Warning, id=_status_id(address))
        for address, record in self.client_book.snapshot().items():
            if self._said_clients.get(address) == record.connected:
                continue
            if record.connected:
                self.get_logger().info(f'client {address} connected')
            else:
                self.get_logger().info(f'client {address} left ({record.full_queue_notices} '
                                       'full-queue notices)')
                self.server.remove_status([_status_id(address)])
            self._said_clients[address] = record.connected

    def _publish_clients_status(self) -> None:
        self._diagnostics.publish(DiagnosticArray(
            header=Header(stamp=self.get_clock().now().to_msg()),
            status=[clients_status(self.client_book, self.settings.client_queue,
                                   self.get_fully_qualified_name())]))
        gone = [a for a, connected in self._said_clients.items() if not connected]
        self.client_book.forget(gone)  # reported once as gone: forgotten now
        for address in gone:
            del self._said_clients[address]

    def _foreign_publishers(self, topic: str) -> list:
        return [info for info in self.get_publishers_info_by_topic(topic)
                if (info.node_name, info.node_namespace)
                != (self.get_name(), self.get_namespace())]

    def _topic_types(self, topic: str) -> List[str]:
        return dict(self.get_topic_names_and_types()).get(topic, [])

    def _tick(self) -> None:
        self._ticks += 1
        self._say_clients()
        if self._ticks % STATUS_TICKS == 0:
            self._publish_clients_status()
        if self._ticks % GRAPH_TICKS == 0:
            self._look_at_graph()
        elif self.topic_channels.changed.is_set():
            self.topic_channels.reconcile(self._foreign_publishers)
        if self.client_publishers.changed.is_set():
            self.client_publishers.make_publishers()
        if self.machine is not None:
            self.machine.tick(lambda: dict(self.get_topic_names_and_types()))

    def _look_at_graph(self) -> None:
        self.topic_channels.update(dict(self.get_topic_names_and_types()),
                                   self._foreign_publishers)
        self.topic_channels.reconcile(self._foreign_publishers)
        me = self.get_fully_qualified_name()
        nodes = [(namespace.rstrip('/') + '/' + name) for name, namespace
                 in self.get_node_names_and_namespaces()]
        self.parameters.track(node for node in nodes if node != me)
        mine = {name for name, _ in self.get_service_names_and_types_by_node(
            self.get_name(), self.get_namespace())}
        self.service_bridge.update({name: types for name, types
                                    in self.get_service_names_and_types() if name not in mine})

    def _on_parameter_event(self, event: ParameterEvent) -> None:
        if event.node == self.get_fully_qualified_name():
            return
        changed = [from_ros(event.node + NODE_SEPARATOR + p.name, p.value)
                   for p in list(event.new_parameters) + list(event.changed_parameters)]
        if changed:
            self.server.publish_parameter_values(changed)

    def close(self) -> None:
        """Stop the server (its clients are disconnected) and let go of the SDK's log."""
        if self.machine is not None:
            self.machine.close()
        self.server.stop()
        logging.getLogger(SDK_LOGGER).removeHandler(self._sdk_log)
