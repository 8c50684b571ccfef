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
A shaper_sim node with a probe node on a background executor, for in-process node tests.

conftest.py hands these out through the `context` and `harness` fixtures; run_ticks drives
the node's publish_at with synthetic stamps, as its timer does with the node clock.
"""

import math

from diagnostic_msgs.msg import DiagnosticArray
from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from ros_probe import BackgroundSpinner, call, wait_for

NS = 1_000_000_000
# The paper's geometry written out (coupling radius r1, crank radius r, pivot distance h, m):
# the tests check against these numbers, not against Geometry.paper().
R1, R, H_PIVOT = 0.025, 0.0505, 0.113


class Harness:
    """A shaper_sim node and a probe node (subscribers, clients) on a background executor."""

    def __init__(self, context, spin_shaper=True, **overrides):
        self.shaper = ShaperSimNode(context=context, parameter_overrides=[
            Parameter(name, value=value) for name, value in overrides.items()])
        self.probe = Node('probe', context=context)
        self.joint_states, self.diagnostics = [], []
        self.probe.create_subscription(JointState, 'joint_states', self.joint_states.append,
                                       1000)
        self.probe.create_subscription(DiagnosticArray, '/diagnostics',
                                       self.diagnostics.append, 1000)
        self.spinner = BackgroundSpinner(context, self.probe,
                                         *([self.shaper] if spin_shaper else []))

    def wait_for(self, predicate, timeout=10.0, what='condition'):
        wait_for(predicate, timeout, what)

    def call(self, service_type, name, request):
        client = self.probe.create_client(service_type, name)
        response = call(client, request)
        self.probe.destroy_client(client)
        return response

    def close(self):
        self.spinner.stop()
        self.shaper.destroy_node()
        self.probe.destroy_node()


def run_ticks(node, start_ns, seconds, rate=100.0, jitter_ns=1_000_000, seed=7,
              wait_for_reports=True):
    """
    Publish at about `rate` with deterministic jitter (as a loaded timer would).

    The node reports stroke pairs on a thread of its own; unless told not to, this returns
    once the pairs completed here are reported.
    """
    stamps, now, period = [], start_ns, int(NS / rate)
    for i in range(int(seconds * rate)):
        now += period + (i * 7919 + seed) % (2 * jitter_ns + 1) - jitter_ns
        assert node.publish_at(now)
        stamps.append(now)
    if wait_for_reports:
        node.wait_for_pair_reports(timeout=30.0)
    return stamps


def all_finite(message):
    """Whether a JointState's positions and velocities are all finite."""
    return all(map(math.isfinite, list(message.position) + list(message.velocity)))


def pair_values(message):
    status, = message.status
    values = {}
    for item in status.values:
        try:
            values[item.key] = float(item.value)
        except ValueError:  # words: 'true', 'false', a definition's name
            values[item.key] = item.value
            continue
        assert math.isfinite(values[item.key]), item
    return values
