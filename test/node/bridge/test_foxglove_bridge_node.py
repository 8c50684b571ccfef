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
"""The bridge node in this process: full client queues counted, said to the clients and on ROS."""

import logging
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from qrm_ros.core.common.names import BRIDGE_CLIENTS_STATUS, DIAGNOSTICS_TOPIC
from qrm_ros.node.bridge.bridge_clients import NOTICE_WINDOW
from qrm_ros.node.bridge.foxglove_bridge import BridgeNode, BridgeSettings
import rclpy
from sensor_msgs.msg import Image

from foxglove_client import FoxgloveClient, node_executable, node_modules
from ros_probe import BackgroundSpinner, wait_for

BULK_TOPIC = '/bulk_images'
BULK_SIZE = 65536  # bytes per image
BULK_RATE = 200.0  # Hz: 13 MB/s, more than the socket buffers hold while a client reads nothing
QUEUE = 64  # messages per client: the stalled client's fills, the reading one's not


@pytest.mark.skipif(node_executable() is None, reason='Node.js is not installed')
def test_a_full_client_queue_is_counted_logged_and_said_to_the_clients(context):
    bridge = BridgeNode(BridgeSettings(port=0, topics=['nothing_here']), context=context)
    spinner = BackgroundSpinner(context, bridge)
    viewer = FoxgloveClient(bridge.address, node_modules())
    try:
        viewer.wait_event('serverInfo')
        # What the SDK logs (through Python's logging) when it drops a client's oldest message.
        logging.getLogger('foxglove.websocket.connected_client.send_lossy').info(
            'outbox for client 127.0.0.1:40000 full')
        wait_for(lambda: bridge.slow_client_notices == {'127.0.0.1:40000': 1})
        status = viewer.wait(lambda events: [e for e in events if e['event'] == 'status'
                                             and 'falls behind' in e['message']],
                             what='the notice as a status')
        assert status[0]['level'] == 1  # a warning
        assert 'client 127.0.0.1:40000 falls behind' in status[0]['message']
        assert 'queue of 1024 messages per client' in status[0]['message']
    finally:
        viewer.close()
        spinner.stop()
        bridge.close()
        bridge.destroy_node()


def _publish_until(stop, publisher):
    message = Image(height=1, width=BULK_SIZE, encoding='mono8', step=BULK_SIZE,
                    data=bytes(BULK_SIZE))
    start, sent = time.monotonic(), 0
    while not stop.is_set():
        stop.wait(max(0.0, start + sent / BULK_RATE - time.monotonic()))  # paced, not a wait
        publisher.publish(message)
        sent += 1


def _clients_statuses(arrays):
    return [status for array in list(arrays) for status in array.status
            if status.name == BRIDGE_CLIENTS_STATUS]


@pytest.mark.skipif(node_executable() is None, reason='Node.js is not installed')
def test_a_stalled_client_is_counted_per_client_in_its_status_and_on_diagnostics(context):
    bridge = BridgeNode(BridgeSettings(port=0, topics=[BULK_TOPIC], client_queue=QUEUE,
                                       send_period=0.0), context=context)
    source = rclpy.create_node('bulk_source', context=context)
    publisher = source.create_publisher(Image, BULK_TOPIC, 10)
    arrays = []
    source.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, arrays.append, 10)
    spinner = BackgroundSpinner(context, bridge, source)
    stop = threading.Event()
    sender = threading.Thread(target=_publish_until, args=(stop, publisher), daemon=True)
    sender.start()
    modules = node_modules()
    viewers = []
    try:
        addresses = []
        for _ in range(2):  # one after the other, to know which address is whose
            viewers.append(FoxgloveClient(bridge.address, modules))
            viewers[-1].send(op='quiet', topic=BULK_TOPIC)
            viewers[-1].send(op='subscribe', topic=BULK_TOPIC)
            viewers[-1].wait_event('subscribed', topic=BULK_TOPIC, timeout=60.0)
            wait_for(lambda: len(bridge.client_book.snapshot()) == len(viewers), 30.0,
                     'the client registered')
            addresses += [a for a in bridge.client_book.snapshot() if a not in addresses]
        (reader, stalled), (reader_address, address) = viewers, addresses
        # Longer than the SDK's 30 s between two notices, in case the reader had one just now.
        stalled.send(op='stall', seconds=NOTICE_WINDOW + 10.0)
        wait_for(lambda: address in bridge.slow_client_notices, NOTICE_WINDOW + 10.0,
                 'the SDK\'s full-queue notice for the stalled client')

        def warned():
            return [s for s in _clients_statuses(arrays) if s.level == s.WARN
                    and address in s.message]
        wait_for(warned, 30.0, 'a clients status naming the stalled client')
        values = {v.key: v.value for v in warned()[-1].values}
        assert values['clients'] == '2'
        assert int(values[f'{address} full-queue notices']) >= 1
        assert f'{reader_address} full-queue notices' in values
        assert values['client queue'] == f'{QUEUE} messages'
        status = reader.wait(lambda events: [e for e in events if e['event'] == 'status'
                                             and f'client {address} falls behind' in e['message']],
                             what='the stalled client\'s status at the other client')
        assert f'queue of {QUEUE} messages per client' in status[0]['message']
        stalled.close()  # stalled: killed after a while

        def said_gone():
            return [s for s in _clients_statuses(arrays)
                    if {v.key: v.value for v in s.values}.get(f'{address} connected') == 'gone']
        wait_for(said_gone, 60.0, 'the stalled client reported gone once it left')
        gone_values = {v.key: v.value for v in said_gone()[-1].values}
        assert gone_values['clients'] == '1'
        assert int(gone_values[f'{address} full-queue notices']) >= 1
    finally:
        stop.set()
        sender.join(timeout=5.0)
        for viewer in viewers:
            viewer.close()
        spinner.stop()
        bridge.close()
        bridge.destroy_node()
        source.destroy_node()
