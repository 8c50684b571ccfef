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
Reaching a Dask scheduler for a fleet (``qrm_analyze --scheduler``), or saying why not.

What is given is checked before Dask sees it: an address with a scheme, a host and a port
in 1-65535, a host name that resolves, something listening there; then Dask's handshake
runs under a deadline of its own, since a server that is not a Dask scheduler (an HTTP
server, a closed-mouthed one) can hold it for ever, and one that sends junk makes Dask
fail in ways that do not say what happened (a ValueError, a MemoryError of exabytes).
"""

import contextlib
import socket
import threading
import traceback
from typing import Any, Dict, Optional, Tuple
from urllib.parse import urlsplit

__all__ = ['connect_to_scheduler', 'SCHEDULER_SCHEMES', 'SCHEDULER_TIMEOUT',
           'scheduler_address_problem', 'SchedulerError']

SCHEDULER_SCHEMES = ('tcp', 'tls', 'ws', 'wss')  # the comms dask.distributed speaks over IP
SCHEDULER_TIMEOUT = 20.0  # s: to connect, and again for Dask's handshake


class SchedulerError(ValueError):
    """The scheduler cannot be reached or does not speak Dask; the message says which."""


def _host_and_port(address: str) -> Tuple[Optional[str], Optional[int], Optional[str]]:
    """Return (host, port, None), or (None, None, what is wrong with the address)."""
    parts = urlsplit(address)
    if parts.scheme not in SCHEDULER_SCHEMES or not parts.netloc:
        return None, None, (f'--scheduler must be a Dask scheduler address such as '
                            f'tcp://HOST:8786 ({", ".join(SCHEDULER_SCHEMES)}), got {address!r}')
    try:
        port = parts.port
    except ValueError:
        port = -1
    if not parts.hostname:
        return None, None, f'--scheduler {address!r} names no host (tcp://HOST:PORT)'
    if port is None or not 1 <= port <= 65535:
        return None, None, f'--scheduler {address!r}: the port must be in 1-65535'
    return parts.hostname, port, None


def scheduler_address_problem(address: str) -> Optional[str]:
    """Say what is wrong with a scheduler address as written (no network), or None."""
    return _host_and_port(address)[2]


def connect_to_scheduler(address: str, timeout: Optional[float] = None) -> Any:
    """
    Return a ``distributed.Client`` of the scheduler at address; SchedulerError if none.

    timeout (s): for the TCP connection, and again for Dask's handshake (None:
    SCHEDULER_TIMEOUT).
    """
    timeout = SCHEDULER_TIMEOUT if timeout is None else timeout
    host, port, problem = _host_and_port(address)
    if problem is not None:
        raise SchedulerError(problem)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except socket.gaierror as error:
        raise SchedulerError(f'the scheduler host {host!r} does not resolve '
                             f'({error.strerror})') from None
    except socket.timeout:
        raise SchedulerError(f'nothing answered at {address} within {timeout:g} s') from None
    except OSError as error:
        raise SchedulerError(f'nothing answers at {address} '
                             f'({error.strerror or error})') from None
    return _handshake(address, timeout)


def _handshake(address: str, timeout: float) -> Any:
    from distributed import Client
    outcome: Dict[str, Any] = {}

    def connect() -> None:
        try:
            outcome['client'] = Client(address, timeout=f'{timeout}s')
        except BaseException as error:  # noqa: B902 - junk makes Dask raise anything
            outcome['error'] = error
            _abandon(Client, error)
    thread = threading.Thread(target=connect, name='dask-handshake', daemon=True)
    thread.start()
    thread.join(timeout + 5.0)
    if thread.is_alive():
        raise SchedulerError(f'{address} accepted the connection but no Dask scheduler '
                             f'answered within {timeout:g} s (is it a Dask scheduler?)')
    error = outcome.get('error')
    if error is not None:
        raise SchedulerError(f'{address} does not answer as a Dask scheduler '
                             f'({type(error).__name__}: {error})') from None
    return outcome['client']


def _abandon(client_class: Any, error: BaseException) -> None:
    """
    Mark the Client that failed in its constructor closed, and stop its event loop.

    Otherwise its finaliser closes it once it is collected, waiting twice the timeout (40 s)
    on a connection that will never answer, and prints that wait's traceback.
    """
    for frame, _ in traceback.walk_tb(error.__traceback__):
        client = frame.f_locals.get('self')
        if isinstance(client, client_class):
            client.status = 'closed'
            with contextlib.suppress(Exception):
                client._loop_runner.stop()
            return
