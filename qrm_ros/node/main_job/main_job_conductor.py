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
The main job's own ROS node: it sets shaper_sim's parameters and counts steady stroke pairs.

The main job (qrm_ros.cli.qrm_main) starts shaper_sim and mcap_recorder as processes; the
Conductor watches them (one that exits ends any wait), waits for them on the ROS graph, sets
parameters through the sim's parameter service (what ``ros2 param set`` calls) and reads the
stroke-pair reports on /diagnostics. It runs in a context of its own and spins only while it
waits.
"""

import signal
import subprocess
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from qrm_ros.core.common.names import (absolute_topic, DIAGNOSTICS_TOPIC, JOINT_STATES_TOPIC,
                                       RECORDER_NODE_NAME, SIM_NODE_NAME, STROKE_PAIR_STATUS)
from qrm_ros.node.process.ros_process import init_rclpy, StopRequest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

__all__ = ['Conductor', 'Interrupted', 'MainJobError', 'PARAMETER_CALL_TIMEOUT', 'SIM_NODE',
           'START_TIMEOUT']

SIM_NODE = '/' + SIM_NODE_NAME
START_TIMEOUT = 30.0  # s, for each child to come up
PARAMETER_CALL_TIMEOUT = 10.0  # s


class MainJobError(Exception):
    """A step of the main job failed; the message says which and what to look at."""


class Interrupted(MainJobError):
    """SIGINT or SIGTERM arrived while recording; the children were stopped cleanly."""

    def __init__(self, signal_number: int, folder: Optional[str] = None):
        text = f'interrupted by {signal.Signals(signal_number).name}'
        if folder:
            text += (f'; shaper_sim and mcap_recorder were stopped, the recording so far is '
                     f'in {folder}')
        super().__init__(text)
        self.signal_number = signal_number


class Conductor:
    """The main job's own ROS node: sets parameters and counts steady stroke pairs."""

    def __init__(self, stop: Optional[StopRequest] = None):
        self._stop_request = stop
        self.context = rclpy.Context()
        init_rclpy(args=[], context=self.context)  # stop signals: StopRequest, not rclpy
        self.node = rclpy.create_node('qrm_main_job', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_parameters = AsyncParameterClient(self.node, SIM_NODE)
        # (name, process, log path): one that exits ends any wait
        self.children: List[Tuple[str, subprocess.Popen, str]] = []
        self.pairs: List[Dict[str, str]] = []
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, 50)

    def _on_diagnostics(self, message: DiagnosticArray) -> None:
        for status in message.status:
            if status.name == STROKE_PAIR_STATUS:
                self.pairs.append({item.key: item.value for item in status.values})

    def watch(self, name: str, process: subprocess.Popen, log_path: str) -> None:
        self.children.append((name, process, log_path))

    def wait_for(self, condition: Callable[[], bool], timeout: float, what: str,
                 interruptible: bool = True) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if interruptible and self._stop_request:
                raise Interrupted(self._stop_request.signal_number)
            for name, process, log_path in self.children if interruptible else ():
                if process.poll() is not None:
                    raise MainJobError(f'{name} exited ({process.returncode}); see {log_path}')
            if time.monotonic() > deadline:
                raise MainJobError(f'timed out after {timeout:g} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.05)

    def sim_ready(self) -> bool:
        return self.sim_parameters.services_are_ready()

    def node_up(self, name: str) -> bool:
        """Whether a node of that name is on the graph (it then handles stop signals)."""
        return name in self.node.get_node_names()

    def let_start(self, children: Sequence[Tuple[str, subprocess.Popen]]) -> None:
        """
        Wait (at most START_TIMEOUT) until each running child's node is up.

        A child signalled while still importing Python would die with a traceback: the
        package's nodes catch stop signals only once they exist.
        """
        self.wait_for(lambda: all(process.poll() is not None or self.node_up(name)
                                  for name, process in children), START_TIMEOUT,
                      'the children to start before stopping them', interruptible=False)

    def recorder_subscribed(self) -> bool:
        infos = self.node.get_subscriptions_info_by_topic(
            absolute_topic(JOINT_STATES_TOPIC))
        return any(info.node_name == RECORDER_NODE_NAME for info in infos)

    def set_parameters(self, **values: float) -> None:
        """Set shaper_sim parameters (floats) as `ros2 param set` does; raise if refused."""
        future = self.sim_parameters.set_parameters(
            [Parameter(name, value=float(value)) for name, value in values.items()])
        self.wait_for(future.done, PARAMETER_CALL_TIMEOUT,
                      f'the answer of {SIM_NODE}/set_parameters')
        for name, result in zip(values, future.result().results):
            if not result.successful:
                raise MainJobError(f'{SIM_NODE} refused {name} = {values[name]}: '
                                   f'{result.reason}')

    def steady_pairs_at(self, offset: Optional[float], since: float,
                        input_speed: Optional[float] = None,
                        stroke_length: Optional[float] = None,
                        time_ratio_held: bool = False) -> int:
        """
        Count steady stroke pairs at an offset (and speed) that began after `since` (s).

        offset None: any; stroke_length (m): within 1e-9 m of it; time_ratio_held: only
        pairs measured while a time ratio was held.
        """
        return sum(1 for pair in self.pairs
                   if pair.get('offset_steady') == 'true'
                   and pair.get('input_speed_steady') == 'true'
                   and pair.get('stroke_steady') != 'false'
                   and pair.get('sampled_without_gap') != 'false'
                   and (offset is None or float(pair.get('coupling_offset', 'nan')) == offset)
                   and (input_speed is None
                        or float(pair.get('input_speed', 'nan')) == input_speed)
                   and (stroke_length is None
                        or abs(float(pair.get('stroke_length', 'nan')) - stroke_length) < 1e-9)
                   and (not time_ratio_held or 'time_ratio_target' in pair)
                   and float(pair.get('pair_start', '-inf')) >= since)

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
