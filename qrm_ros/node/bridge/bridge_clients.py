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
The bridge's clients as the SDK tells of them: who is connected, whose queue ran full.

The SDK (foxglove-sdk 0.30) keeps one bounded queue per client (``message_backlog_size``
messages) and, when a message finds it full, drops that client's oldest to make room. It
counts nothing it drops and offers no per-client callback or status; what it does say, through
Python's logging, is "Registered client ADDRESS", "Unregistered client ADDRESS" and "outbox for
client ADDRESS full" (that last one at most once per 30 s for all clients together). So the
bridge counts those notices per client address: each one stands for at least one dropped
message (so the count is a lower bound, and a coarse one: the SDK says nothing of the
messages it drops within 30 s of its last notice). ``ClientBook`` keeps
the book; ``clients_status`` writes it as the ``qrm_bridge: clients`` diagnostics status.
"""

import threading
import time
from typing import Dict, List, Optional

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from qrm_ros.core.common.names import BRIDGE_CLIENTS_STATUS

__all__ = ['ClientBook', 'ClientRecord', 'FULL_QUEUE_NOTICE', 'NOTICE_WINDOW',
           'REGISTERED_NOTICE', 'UNREGISTERED_NOTICE', 'clients_status']

# The SDK's log texts (its tracing events, at INFO), each followed by the client's address.
REGISTERED_NOTICE = 'Registered client '
UNREGISTERED_NOTICE = 'Unregistered client '
FULL_QUEUE_NOTICE = 'outbox for client '
NOTICE_WINDOW = 30.0  # s, the SDK's least interval between two full-queue notices


class ClientRecord:
    """One client address: since when it is connected, its full-queue notices."""

    def __init__(self, connected_at: float):
        self.connected_at = connected_at
        self.connected = True
        self.full_queue_notices = 0
        self.last_notice_at: Optional[float] = None


class ClientBook:
    """
    The clients by address, fed from the SDK's log notices (any thread).

    ``read`` returns True when the text was one of the notices above. A client that leaves
    stays in the book, marked gone, until ``forget`` (after it was reported once).
    """

    def __init__(self, clock=time.monotonic):
        self._clock = clock
        self._lock = threading.Lock()
        self._clients: Dict[str, ClientRecord] = {}
        self.pending_notices: List[str] = []  # addresses with a full queue not yet said

    def read(self, text: str) -> bool:
        """Note a notice of the SDK's log; return whether the text was one."""
        for prefix, note in ((FULL_QUEUE_NOTICE, self._full), (REGISTERED_NOTICE, self._came),
                             (UNREGISTERED_NOTICE, self._went)):
            if text.startswith(prefix):
                words = text[len(prefix):].split()
                if words:
                    with self._lock:
                        note(words[0])
                return True
        return False

    def _record(self, address: str) -> ClientRecord:
        if address not in self._clients:
            self._clients[address] = ClientRecord(self._clock())
        return self._clients[address]

    def _came(self, address: str) -> None:
        self._clients[address] = ClientRecord(self._clock())

    def _went(self, address: str) -> None:
        self._record(address).connected = False

    def _full(self, address: str) -> None:
        record = self._record(address)
        record.full_queue_notices += 1
        record.last_notice_at = self._clock()
        self.pending_notices.append(address)

    def take_pending(self) -> List[str]:
        """Return the addresses whose full queue is not yet said, and forget them."""
        with self._lock:
            pending, self.pending_notices = self.pending_notices, []
        return pending

    def snapshot(self) -> Dict[str, ClientRecord]:
        """Address -> a copy of its record."""
        with self._lock:
            copies = {}
            for address, record in self._clients.items():
                copy = ClientRecord(record.connected_at)
                copy.__dict__.update(record.__dict__)
                copies[address] = copy
            return copies

    def notices(self) -> Dict[str, int]:
        """Address -> full-queue notices so far (the clients gone included, until forgotten)."""
        with self._lock:
            return {a: r.full_queue_notices for a, r in self._clients.items()}

    def forget(self, addresses: List[str]) -> None:
        """Drop these clients if they have left (once their leaving was reported)."""
        with self._lock:
            for address in addresses:
                if address in self._clients and not self._clients[address].connected:
                    del self._clients[address]


def clients_status(book: ClientBook, client_queue: int, hardware_id: str,
                   now: Optional[float] = None) -> DiagnosticStatus:
    """
    Write the book as the ``qrm_bridge: clients`` status: each client's full-queue notices.

    WARN while a connected client had a notice in the last 30 s (the SDK says one at most
    that often), else OK. Keys: ``clients`` (connected), ``client queue`` (messages), and per
    client ``ADDRESS full-queue notices`` and ``ADDRESS connected s`` (or ``gone``).
    """
    now = time.monotonic() if now is None else now
    records = book.snapshot()
    connected = {a: r for a, r in records.items() if r.connected}
    behind = sorted(a for a, r in connected.items()
                    if r.last_notice_at is not None and now - r.last_notice_at <= NOTICE_WINDOW)
    values = [KeyValue(key='clients', value=str(len(connected))),
              KeyValue(key='client queue', value=f'{client_queue} messages')]
    for address in sorted(records):
        record = records[address]
        values.append(KeyValue(key=f'{address} full-queue notices',
                               value=str(record.full_queue_notices)))
        values.append(KeyValue(key=f'{address} connected',
                               value=f'{now - record.connected_at:.0f} s' if record.connected
                               else 'gone'))
    if behind:
        level = DiagnosticStatus.WARN
        message = (f'{", ".join(behind)} fall(s) behind: oldest messages dropped (queue of '
                   f'{client_queue} messages per client)')
    else:
        level = DiagnosticStatus.OK
        message = f'{len(connected)} client(s), none behind'
    return DiagnosticStatus(level=level, name=BRIDGE_CLIENTS_STATUS, message=message,
                            hardware_id=hardware_id, values=values)
