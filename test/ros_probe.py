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
Shared pieces of the ROS tests: spin nodes in the background, wait on conditions, call services.

Tests never sleep for a fixed time: they wait for a condition with a timeout, while the nodes
under test (or probing them) are spun on a daemon thread.
"""

import os
import shutil
import signal
import subprocess
import threading
import time

from ament_index_python.packages import get_package_prefix, PackageNotFoundError
from rclpy.executors import SingleThreadedExecutor


def installed_executable(name):
    """
    Path of a qrm_ros console script, or None.

    Looked up where `ros2 run` looks first (<prefix>/lib/qrm_ros, the colcon layout), then on
    PATH (a pip install puts the scripts in the environment's bin/).
    """
    try:
        found = os.path.join(get_package_prefix('qrm_ros'), 'lib', 'qrm_ros', name)
    except PackageNotFoundError:
        found = None
    if found and os.access(found, os.X_OK):
        return found
    return shutil.which(name)


def stamp_ns(message):
    """Return a stamped message's header stamp in integer nanoseconds."""
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def wait_for(predicate, timeout=10.0, what='condition'):
    """Poll predicate until true; fail the test after timeout seconds, naming what it awaited."""
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f'timed out after {timeout} s waiting for {what}'
        time.sleep(0.005)


def stop_process(popen, signal_number=signal.SIGINT, timeout=10.0):
    """
    Send a stop signal (SIGINT by default), wait; return the exit code.

    A process that does not stop within timeout seconds is killed and the test fails, naming
    the process and the signal it ignored.
    """
    if popen.poll() is None:
        popen.send_signal(signal_number)
    try:
        return popen.wait(timeout)
    except subprocess.TimeoutExpired:
        popen.kill()
        popen.wait()
        raise AssertionError(f'{popen.args[0]} (pid {popen.pid}) ignored '
                             f'{signal.Signals(signal_number).name} for {timeout} s') from None


def call(client, request, timeout=10.0):
    """Call a service (on a node spun elsewhere) and return its response."""
    assert client.wait_for_service(timeout_sec=timeout), f'no service {client.srv_name}'
    future = client.call_async(request)
    wait_for(future.done, timeout, f'{client.srv_name} response')
    return future.result()


class BackgroundSpinner:
    """Spin some nodes of one context on a daemon thread until stop()."""

    def __init__(self, context, *nodes):
        self.context = context
        self.executor = SingleThreadedExecutor(context=context)
        for node in nodes:
            self.executor.add_node(node)
        self._running = True
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while self._running and self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.02)
            except Exception:  # the context was shut down under us: nothing left to spin
                return

    def stop(self):
        self._running = False
        self._thread.join(timeout=5.0)
        self.executor.shutdown()
