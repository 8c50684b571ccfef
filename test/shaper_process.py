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
"""The shaper_sim executable as its own process, and a probe beside it (over real DDS)."""

import math
import os
import signal
import subprocess
import tempfile

from ament_index_python.packages import get_package_share_directory
from rcl_interfaces.srv import GetParameters, SetParameters
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from sensor_msgs.msg import JointState

from ros_probe import BackgroundSpinner, call, installed_executable, wait_for


NS = 1_000_000_000


def executable():
    found = installed_executable('shaper_sim')
    assert found, 'the shaper_sim console script is not installed (lib/qrm_ros nor PATH)'
    return found


class Process:
    """shaper_sim started from its installed parameter file, output kept in files."""

    def __init__(self, *arguments, environment=None):
        self.output = tempfile.TemporaryFile(mode='w+')
        parameters = os.path.join(get_package_share_directory('qrm_ros'), 'config',
                                  'shaper.yaml')
        self.process = subprocess.Popen(
            [executable(), '--ros-args', '--params-file', parameters, *arguments],
            stdout=self.output, stderr=subprocess.STDOUT, text=True,
            env=None if environment is None else dict(os.environ, **environment))

    def stop(self, signal_number=signal.SIGINT, timeout=10.0):
        """Send signal_number (None: just wait) and return (exit code, output)."""
        if signal_number is not None and self.process.poll() is None:
            self.process.send_signal(signal_number)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise
        self.output.seek(0)
        return code, self.output.read()


class Probe:
    """Subscriber and parameter clients in this process, spun on a background thread."""

    def __init__(self):
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node('process_probe', context=self.context)
        self.messages = []
        self.joint_states = self.node.create_subscription(
            JointState, 'joint_states', self.messages.append, 1000)
        self.set_client = self.node.create_client(SetParameters, '/shaper_sim/set_parameters')
        self.get_client = self.node.create_client(GetParameters, '/shaper_sim/get_parameters')
        self.spinner = BackgroundSpinner(self.context, self.node)

    def wait_for(self, predicate, timeout=15.0, what='condition'):
        wait_for(predicate, timeout, what)

    def wait_for_discovery(self):
        """
        Wait until the node's joint states and parameter services are matched here.

        Discovery goes on for a while after a node's first endpoint is seen (a node has
        dozens), and on a loaded 2-core machine its bursts held a new node's timer back for
        a quarter of a second: a test that counts samples starts after it.
        """
        self.wait_for(lambda: self.joint_states.get_publisher_count() > 0,
                      what="the node's joint states matched")
        for client in (self.set_client, self.get_client):
            assert client.wait_for_service(timeout_sec=15.0), f'{client.srv_name} not found'

    def call(self, client, request):
        return call(client, request, timeout=15.0)

    def set_parameter(self, name, value):
        """One parameter per request, as `ros2 param set` sends it."""
        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])
        result, = self.call(self.set_client, request).results
        return result

    def get_parameters(self, names):
        response = self.call(self.get_client, GetParameters.Request(names=names))
        return {name: parameter_value_to_python(value)
                for name, value in zip(names, response.values)}

    def close(self):
        self.spinner.stop()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def wrapped(angle):
    return math.remainder(angle, 2 * math.pi)
