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
"""The bridge node in this process: the SDK's notice of a full client queue reaches the clients."""

import logging

import pytest
from qrm_ros.node.foxglove_bridge import BridgeNode, BridgeSettings

from foxglove_client import FoxgloveClient, node_executable, node_modules
from ros_probe import BackgroundSpinner, wait_for


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
