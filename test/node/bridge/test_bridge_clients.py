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
"""The book of the bridge's clients, read from the SDK's log texts, and its diagnostics status."""

from diagnostic_msgs.msg import DiagnosticStatus
from qrm_ros.core.common.names import BRIDGE_CLIENTS_STATUS
from qrm_ros.node.bridge.bridge_clients import ClientBook, clients_status, NOTICE_WINDOW


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def _values(status):
    return {value.key: value.value for value in status.values}


def test_the_sdks_notices_are_counted_per_client_address():
    clock = Clock()
    book = ClientBook(clock)
    # The texts the SDK logs (foxglove-sdk 0.30, at INFO), as the bridge receives them.
    assert book.read('Registered client 127.0.0.1:50001')
    assert book.read('Registered client 127.0.0.1:50002')
    assert not book.read('Started server on 127.0.0.1:8765')
    assert not book.read('Connection closed by client 127.0.0.1:50002')
    clock.now = 103.0
    assert book.read('outbox for client 127.0.0.1:50002 full')
    clock.now = 140.0
    assert book.read('outbox for client 127.0.0.1:50002 full')
    assert book.notices() == {'127.0.0.1:50001': 0, '127.0.0.1:50002': 2}
    assert book.take_pending() == ['127.0.0.1:50002', '127.0.0.1:50002']
    assert book.take_pending() == []
    status = clients_status(book, 16, '/qrm_bridge', now=150.0)
    assert (status.name, status.level) == (BRIDGE_CLIENTS_STATUS, DiagnosticStatus.WARN)
    assert status.message.startswith('127.0.0.1:50002 fall(s) behind')
    assert _values(status) == {
        'clients': '2', 'client queue': '16 messages',
        '127.0.0.1:50001 full-queue notices': '0', '127.0.0.1:50001 connected': '50 s',
        '127.0.0.1:50002 full-queue notices': '2', '127.0.0.1:50002 connected': '50 s'}


def test_a_client_is_ok_again_once_the_sdk_has_said_nothing_for_its_notice_window():
    clock = Clock()
    book = ClientBook(clock)
    book.read('Registered client [::1]:50003')
    book.read('outbox for client [::1]:50003 full')
    assert clients_status(book, 8, '', now=clock.now + NOTICE_WINDOW).level == \
        DiagnosticStatus.WARN
    later = clients_status(book, 8, '', now=clock.now + NOTICE_WINDOW + 1.0)
    assert later.level == DiagnosticStatus.OK
    assert later.message == '1 client(s), none behind'
    assert _values(later)['[::1]:50003 full-queue notices'] == '1'  # the count stays


def test_a_client_that_left_is_reported_gone_then_forgotten():
    clock = Clock()
    book = ClientBook(clock)
    book.read('Registered client 127.0.0.1:50004')
    book.read('outbox for client 127.0.0.1:50004 full')
    book.read('Unregistered client 127.0.0.1:50004')
    book.read('Registered client 127.0.0.1:50005')
    status = clients_status(book, 8, '', now=clock.now)
    values = _values(status)
    assert values['clients'] == '1'
    assert values['127.0.0.1:50004 connected'] == 'gone'
    assert values['127.0.0.1:50004 full-queue notices'] == '1'
    assert status.level == DiagnosticStatus.OK  # only connected clients can be behind
    book.forget(['127.0.0.1:50004', '127.0.0.1:50005'])  # a connected one is kept
    assert book.notices() == {'127.0.0.1:50005': 0}
