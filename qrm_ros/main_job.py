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
The main job: a whole recorded experiment, from a cold start to TR/SR tables and figures.

It starts ``shaper_sim`` and ``mcap_recorder`` as their own processes (real DDS on this host),
steps the coupling offset through a schedule by the node's parameter service (what
``ros2 param set /shaper_sim coupling_offset ...`` calls), moves on once the node's
diagnostics report enough steady stroke pairs at each offset, stops the recorder cleanly
(SIGINT), and analyses the recording offline like ``qrm_analyze --plot``.
"""

import argparse
from datetime import datetime
import math
import os
import signal
import subprocess
import sys
import time

from qrm_ros import analysis
from qrm_ros import kinematics as kin
from qrm_ros.figures import write_figures
from qrm_ros.names import (absolute_topic, DIAGNOSTICS_TOPIC, JOINT_STATES_TOPIC,
                           RECORDER_NODE_NAME, SIM_NODE_NAME, STROKE_PAIR_STATUS)

SIM_NODE = '/' + SIM_NODE_NAME
# Both signs, and the offset of equal mid-stroke speeds (SR = 1, paper eq. 26: -r r1 / h).
UNITY_SPEED_RATIO_MM = kin.offset_for_speed_ratio(kin.Geometry.paper(), 1.0) * 1e3
DEFAULT_OFFSETS_MM = [-15.0, UNITY_SPEED_RATIO_MM, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0]
# Margin after the recorder's subscription appears before its data is surely flowing.
RECORDER_SETTLE_TIME = 0.5


class MainJobError(Exception):
    """A step of the main job failed; the message says which and what to look at."""


def _start(module, ros_arguments, log_path, env):
    """Start a package executable as its own process (works in a venv and under colcon)."""
    command = [sys.executable, '-c', f'import sys; from qrm_ros.{module} import main; '
               'sys.exit(main())', '--ros-args'] + ros_arguments
    with open(log_path, 'w') as log:  # the child keeps its own copy of the descriptor
        return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env,
                                start_new_session=True)


def _stop(process, timeout=15.0):
    """SIGINT (a clean finish), then SIGKILL if it hangs; return the exit code."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode


class Conductor:
    """The main job's own ROS node: sets parameters and counts steady stroke pairs."""

    def __init__(self):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rcl_interfaces.srv import SetParameters
        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, args=[])
        self.node = rclpy.create_node('qrm_main_job', context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.set_client = self.node.create_client(SetParameters,
                                                  SIM_NODE + '/set_parameters')
        self.pairs = []
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, 50)

    def _on_diagnostics(self, message):
        for status in message.status:
            if status.name == STROKE_PAIR_STATUS:
                self.pairs.append({item.key: item.value for item in status.values})

    def wait_for(self, condition, timeout, what):
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise MainJobError(f'timed out after {timeout:g} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.05)

    def recorder_subscribed(self):
        infos = self.node.get_subscriptions_info_by_topic(
            absolute_topic(JOINT_STATES_TOPIC))
        return any(info.node_name == RECORDER_NODE_NAME for info in infos)

    def set_parameters(self, **values):
        """Set shaper_sim parameters (floats) as `ros2 param set` does; raise if refused."""
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters
        request = SetParameters.Request(parameters=[Parameter(
            name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                            double_value=float(value)))
            for name, value in values.items()])
        future = self.set_client.call_async(request)
        self.wait_for(future.done, 10.0, 'the answer of /shaper_sim/set_parameters')
        for name, result in zip(values, future.result().results):
            if not result.successful:
                raise MainJobError(f'/shaper_sim refused {name} = {values[name]}: '
                                   f'{result.reason}')

    def steady_pairs_at(self, offset, since, input_speed=None):
        """Count steady stroke pairs at an offset (and speed) that began after `since` (s)."""
        return sum(1 for pair in self.pairs
                   if pair.get('offset_steady') == 'true'
                   and pair.get('input_speed_steady') == 'true'
                   and float(pair.get('coupling_offset', 'nan')) == offset
                   and (input_speed is None
                        or float(pair.get('input_speed', 'nan')) == input_speed)
                   and float(pair.get('pair_start', '-inf')) >= since)

    def close(self):
        self.node.destroy_node()
        self._rclpy.shutdown(context=self.context)


def _options(argv):
    parser = argparse.ArgumentParser(
        prog='qrm_main', description='Run shaper_sim through a schedule of coupling offsets, '
        'record it to MCAP and report measured vs theoretical time and speed ratios.')
    parser.add_argument('--offsets-mm', type=float, nargs='+', default=DEFAULT_OFFSETS_MM,
                        help='offset schedule [mm] (default: -15, -r r1/h = '
                        f'{UNITY_SPEED_RATIO_MM:.4f} (SR = 1), -10, -5, 0, 5, 10, 15)')
    parser.add_argument('--input-speed', type=float, default=2 * math.pi,
                        help='input shaft speed [rad/s] (default: 2 pi = 60 rpm)')
    parser.add_argument('--pairs', type=int, default=3,
                        help='steady stroke pairs to record at each offset (default: 3)')
    parser.add_argument('--publish-rate', type=float, default=100.0,
                        help='shaper_sim publish rate [Hz] (default: 100)')
    parser.add_argument('--offset-rate-limit', type=float, default=0.02,
                        help='offset actuator speed [m/s] (default: 0.02)')
    parser.add_argument('--output-dir', default='runs',
                        help='folder for the run folder (default: runs)')
    return parser.parse_args(argv)


def run(options):
    """Run the experiment; return the run folder."""
    if options.pairs < 1:
        raise MainJobError(f'--pairs must be at least 1, got {options.pairs}')
    if options.input_speed == 0.0 or not math.isfinite(options.input_speed):
        raise MainJobError(f'--input-speed must be finite and non-zero, got '
                           f'{options.input_speed}')
    offsets = [value / 1e3 for value in options.offsets_mm]
    geometry = kin.Geometry.paper()  # shaper_sim's default geometry
    for offset in offsets:
        try:
            kin.check_offset(geometry, offset, geometry.max_safe_offset)
        except kin.KinematicsError:
            raise MainJobError(f'--offsets-mm: {offset * 1e3:g} mm is outside what shaper_sim '
                               f'accepts, |offset| <= {geometry.max_safe_offset * 1e3:g} mm'
                               ) from None
    folder = os.path.join(options.output_dir,
                          datetime.now().strftime('qrm_%Y%m%d_%H%M%S_%f')[:-3])
    os.makedirs(folder)
    recording = os.path.join(folder, 'run.mcap')
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.update(env)
    print(f'qrm_main: run folder {folder}', flush=True)
    sim = _start('shaper_sim', [
        '-p', f'coupling_offset:={offsets[0]!r}', '-p', f'input_speed:={options.input_speed!r}',
        '-p', f'publish_rate:={float(options.publish_rate)!r}',
        '-p', f'offset_rate_limit:={float(options.offset_rate_limit)!r}',
    ], os.path.join(folder, 'shaper_sim.log'), env)
    recorder = None
    conductor = Conductor()
    try:
        conductor.wait_for(lambda: conductor.set_client.service_is_ready() or sim.poll(), 30.0,
                           'shaper_sim to start')
        if sim.poll() is not None:
            raise MainJobError(f'shaper_sim exited ({sim.returncode}); see {folder}/'
                               'shaper_sim.log')
        recorder = _start('recorder', ['-p', f'output:={recording}'],
                          os.path.join(folder, 'mcap_recorder.log'), env)
        conductor.wait_for(lambda: conductor.recorder_subscribed() or recorder.poll(), 30.0,
                           'mcap_recorder to subscribe')
        if recorder.poll() is not None:
            raise MainJobError(f'mcap_recorder exited ({recorder.returncode}); see {folder}/'
                               'mcap_recorder.log')
        period = 2 * math.pi / abs(options.input_speed)
        # Pairs that began before the recorder was surely receiving do not count.
        recording_since = time.time() + RECORDER_SETTLE_TIME
        for offset in offsets:
            conductor.set_parameters(coupling_offset=offset)
            started = time.monotonic()
            conductor.wait_for(lambda: conductor.steady_pairs_at(
                offset, recording_since) >= options.pairs,
                               (options.pairs + 3) * period + 20.0,
                               f'{options.pairs} steady stroke pairs at offset {offset} m')
            print(f'qrm_main: offset {offset * 1e3:+7.2f} mm: {options.pairs} steady stroke '
                  f'pairs in {time.monotonic() - started:.1f} s', flush=True)
    finally:
        conductor.close()
        if recorder is not None and _stop(recorder) != 0:
            print(f'qrm_main: warning: mcap_recorder exited with {recorder.returncode}; see '
                  f'{folder}/mcap_recorder.log', file=sys.stderr)
        _stop(sim)
    result = analysis.analyse(analysis.read_recording(recording))
    print()
    print(analysis.format_table(result))
    analysis.write_json(result, os.path.join(folder, 'results.json'))
    analysis.write_csv(result, os.path.join(folder, 'results.csv'))
    figures = write_figures(result, os.path.join(folder, 'figures'))
    print()
    print(f'qrm_main: recording  {recording}')
    print(f'qrm_main: results    {os.path.join(folder, "results.json")}, '
          f'{os.path.join(folder, "results.csv")}')
    for path in figures:
        print(f'qrm_main: figure     {path}')
    return folder


def main(argv=None):
    options = _options(argv)
    try:
        run(options)
    except (MainJobError, analysis.AnalysisError) as error:
        print(f'qrm_main: error: {error}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print('qrm_main: interrupted', file=sys.stderr)
        return 130
    return 0


if __name__ == '__main__':
    sys.exit(main())
