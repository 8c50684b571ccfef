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
Foxglove's own protocol client (npm, run with Node.js) for the bridge tests and benchmark.

The npm packages are installed once per set of pinned versions into a cache folder outside the
repository (``~/.cache/qrm_ros/npm/<versions>``, or under ``QRM_ROS_NPM_CACHE``); nothing is
written into the repository. ``FoxgloveClient`` runs ``foxglove_ws_client.js`` and collects what
the server says as JSON events.
"""

import fcntl
import hashlib
import json
import os
import re
import shutil
import subprocess
import threading
import time

from qrm_ros.core.common.names import BRIDGE_SERVING_PREFIX

from repo_paths import TEST_FOLDER

# Foxglove's protocol client and its ROS 2 message definition parser and CDR reader/writer.
NPM_PACKAGES = ('@foxglove/ws-protocol@0.8.0', '@foxglove/rosmsg@5.0.5',
                '@foxglove/rosmsg2-serialization@3.1.0')
CLIENT_SCRIPT = os.path.join(TEST_FOLDER, 'foxglove_ws_client.js')
NPM_INSTALL_TIMEOUT = 300.0  # s
ADDRESS_LINE = re.compile(re.escape(BRIDGE_SERVING_PREFIX) + r'(ws://\S+)')


def node_executable():
    """Node.js, or None when it is not installed."""
    return shutil.which('node')


def node_modules():
    """Install the pinned npm packages once (shared by concurrent runs); return node_modules."""
    root = os.environ.get('QRM_ROS_NPM_CACHE') or os.path.join(
        os.path.expanduser('~'), '.cache', 'qrm_ros', 'npm')
    key = hashlib.sha256(' '.join(NPM_PACKAGES).encode()).hexdigest()[:16]
    folder = os.path.join(root, key)
    done = os.path.join(folder, 'installed')
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, '.lock'), 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not os.path.exists(done):
            with open(os.path.join(folder, 'package.json'), 'w') as handle:
                json.dump({'private': True, 'description': 'qrm_ros test client'}, handle)
            result = subprocess.run(
                ['npm', 'install', '--no-audit', '--no-fund', '--no-save', '--prefix', folder,
                 *NPM_PACKAGES], capture_output=True, text=True, timeout=NPM_INSTALL_TIMEOUT)
            assert result.returncode == 0, f'npm install failed: {result.stderr[-2000:]}'
            with open(done, 'w') as handle:
                handle.write('\n'.join(NPM_PACKAGES) + '\n')
    return os.path.join(folder, 'node_modules')


def node_arguments():
    """Node 20 has WebSocket behind a flag; 22 and later have it by default."""
    version = subprocess.run([node_executable(), '--version'], capture_output=True,
                             text=True).stdout.strip().lstrip('v')
    return ['--experimental-websocket'] if int(version.split('.')[0]) < 22 else []


def bridge_address(process, output_lines, timeout=30.0):
    """Read the bridge's stdout until it says its address (the rest: in the background)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        output_lines.append(line)
        found = ADDRESS_LINE.search(line)
        if found:
            # Keep reading what it logs, so a full pipe never holds the bridge up.
            threading.Thread(target=lambda: output_lines.extend(process.stdout),
                             daemon=True).start()
            return found.group(1)
    raise AssertionError(f'qrm_bridge said no address: {"".join(output_lines)[-2000:]}')


class FoxgloveClient:
    """One connection of Foxglove's client: send commands, wait for the server's events."""

    def __init__(self, address, modules):
        self.events = []
        self._condition = threading.Condition()
        self.process = subprocess.Popen(
            [node_executable(), *node_arguments(), CLIENT_SCRIPT, address],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=dict(os.environ, NODE_PATH=modules))
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stdout:
            event = json.loads(line)
            with self._condition:
                self.events.append(event)
                self._condition.notify_all()

    def send(self, **command):
        self.process.stdin.write(json.dumps(command) + '\n')
        self.process.stdin.flush()

    def matching(self, event, **fields):
        with self._condition:
            return [e for e in self.events if e.get('event') == event
                    and all(e.get(k) == v for k, v in fields.items())]

    def wait(self, predicate, timeout=20.0, what='an event'):
        """Wait until predicate(events) is truthy; return its value."""
        deadline = time.monotonic() + timeout
        with self._condition:
            while True:
                value = predicate(self.events)
                if value:
                    return value
                left = deadline - time.monotonic()
                assert left > 0, (f'timed out after {timeout} s waiting for {what}; last '
                                  f'events: {self.events[-5:]}')
                self._condition.wait(min(left, 0.1))

    def wait_event(self, event, timeout=20.0, **fields):
        """Wait for the first event of that kind with those fields; return it."""
        def first(events):
            return next((e for e in events if e.get('event') == event
                         and all(e.get(k) == v for k, v in fields.items())), None)
        return self.wait(first, timeout, f'{event} {fields}')

    def close(self):
        if self.process.poll() is None:
            try:
                self.send(op='close')
                self.process.wait(5.0)
            except (OSError, subprocess.TimeoutExpired):
                self.process.kill()
                self.process.wait()
