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

Exit codes: 0 done, 1 a failure while running (a child that exits, a time-out, a refused
setting, an analysis error), 2 bad options (argparse), 128 + the signal number when stopped
by SIGINT (130, Ctrl-C) or SIGTERM (143); the children are stopped cleanly either way.
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
from qrm_ros.cli.exit_codes import EXIT_INCOMPLETE
from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics import DynamicsError, Loads
from qrm_ros.core.names import (absolute_topic, DIAGNOSTICS_TOPIC, DRIVES, JOINT_STATES_TOPIC,
                                LINKAGE_MARKERS_TOPIC, RECORDER_NODE_NAME, SIM_NODE_NAME,
                                STROKE_PAIR_STATUS)
from qrm_ros.node.recorder import DEFAULT_TOPICS
from qrm_ros.node.ros_process import init_rclpy, StopRequest

SIM_NODE = '/' + SIM_NODE_NAME
# Both signs, and the offset of equal mid-stroke speeds (SR = 1, paper eq. 26: -r r1 / h).
UNITY_SPEED_RATIO_MM = kin.offset_for_speed_ratio(kin.Geometry.paper(), 1.0) * 1e3
DEFAULT_OFFSETS_MM = [-15.0, UNITY_SPEED_RATIO_MM, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0]
# Margin after the recorder's subscription appears before its data is surely flowing.
RECORDER_SETTLE_TIME = 0.5
START_TIMEOUT = 30.0  # s, for each child to come up
PARAMETER_CALL_TIMEOUT = 10.0  # s
CHILD_STOP_TIMEOUT = 15.0  # s, after SIGINT, before SIGKILL
# Beside the figures: one input revolution at each of a few offsets (qrm_ros.analysis.animation).
TOUR_FILE = 'offset_tour.gif'


class MainJobError(Exception):
    """A step of the main job failed; the message says which and what to look at."""


class UsageError(MainJobError):
    """An option outside what the job accepts (exit code 2)."""


class Interrupted(MainJobError):
    """SIGINT or SIGTERM arrived while recording; the children were stopped cleanly."""

    def __init__(self, signal_number, folder=None):
        text = f'interrupted by {signal.Signals(signal_number).name}'
        if folder:
            text += (f'; shaper_sim and mcap_recorder were stopped, the recording so far is '
                     f'in {folder}')
        super().__init__(text)
        self.signal_number = signal_number


def _start(command_name, ros_arguments, log_path, env):
    """Start a package executable as its own process (works in a venv and under colcon)."""
    # Through the console script's entry point, so a stop during start-up is quiet too.
    command = [sys.executable, '-c', 'import sys; from qrm_ros.cli import entry_points; '
               f'sys.exit(entry_points.{command_name}())', '--ros-args'] + ros_arguments
    with open(log_path, 'w') as log:  # the child keeps its own copy of the descriptor
        return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env,
                                start_new_session=True)


def _stop(process, timeout=CHILD_STOP_TIMEOUT):
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

    def __init__(self, stop=None):
        import rclpy
        from rclpy.parameter_client import AsyncParameterClient
        from diagnostic_msgs.msg import DiagnosticArray
        self._rclpy = rclpy
        self._stop_request = stop
        self.context = rclpy.Context()
        init_rclpy(args=[], context=self.context)  # stop signals: StopRequest, not rclpy
        self.node = rclpy.create_node('qrm_main_job', context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_parameters = AsyncParameterClient(self.node, SIM_NODE)
        self.children = []  # (name, process, log path): one that exits ends any wait
        self.pairs = []
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, 50)

    def _on_diagnostics(self, message):
        for status in message.status:
            if status.name == STROKE_PAIR_STATUS:
                self.pairs.append({item.key: item.value for item in status.values})

    def watch(self, name, process, log_path):
        self.children.append((name, process, log_path))

    def wait_for(self, condition, timeout, what, interruptible=True):
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

    def sim_ready(self):
        return self.sim_parameters.services_are_ready()

    def node_up(self, name):
        """Whether a node of that name is on the graph (it then handles stop signals)."""
        return name in self.node.get_node_names()

    def let_start(self, children):
        """
        Wait (at most START_TIMEOUT) until each running child's node is up.

        A child signalled while still importing Python would die with a traceback: the
        package's nodes catch stop signals only once they exist.
        """
        self.wait_for(lambda: all(process.poll() is not None or self.node_up(name)
                                  for name, process in children), START_TIMEOUT,
                      'the children to start before stopping them', interruptible=False)

    def recorder_subscribed(self):
        infos = self.node.get_subscriptions_info_by_topic(
            absolute_topic(JOINT_STATES_TOPIC))
        return any(info.node_name == RECORDER_NODE_NAME for info in infos)

    def set_parameters(self, **values):
        """Set shaper_sim parameters (floats) as `ros2 param set` does; raise if refused."""
        from rclpy.parameter import Parameter
        future = self.sim_parameters.set_parameters(
            [Parameter(name, value=float(value)) for name, value in values.items()])
        self.wait_for(future.done, PARAMETER_CALL_TIMEOUT,
                      f'the answer of {SIM_NODE}/set_parameters')
        for name, result in zip(values, future.result().results):
            if not result.successful:
                raise MainJobError(f'{SIM_NODE} refused {name} = {values[name]}: '
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
        self._rclpy.try_shutdown(context=self.context)


def _parser():
    parser = argparse.ArgumentParser(
        prog='qrm_main', description='Run shaper_sim through a schedule of coupling offsets, '
        'record it to MCAP and report measured vs theoretical time and speed ratios.',
        epilog='Exit codes: 0 done, 1 a failure while running, 2 bad options, 130 Ctrl-C, '
               '143 SIGTERM.')
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
    loads = Loads.small_shaper()
    parser.add_argument('--cutting-force', type=float, default=loads.cutting_force,
                        help='cutting force on the ram while the tool is in the work [N] '
                        f'(default: {loads.cutting_force:g}, the small shaper of '
                        'dynamics.Loads.small_shaper; 0: no cutting)')
    parser.add_argument('--ram-friction', type=float, default=loads.ram_friction,
                        help=f'Coulomb friction on the ram [N] (default: {loads.ram_friction:g})')
    parser.add_argument('--cutting-length', type=float, default=loads.cutting_length,
                        help='workpiece length, centred on ram position 0 [m] (default: '
                        f'{loads.cutting_length:g})')
    parser.add_argument('--drive', choices=DRIVES, default=DRIVES[0],
                        help="'speed': an ideal speed source (the ratios then match theory "
                        "exactly); 'motor': the small shaper's motor, whose speed fluctuates "
                        'with the load (default: speed)')
    parser.add_argument('--output-dir', default='runs',
                        help='folder for the run folder (default: runs)')
    return parser


def validate(options):
    """Refuse options the run cannot use, before anything starts (raises UsageError)."""
    if options.pairs < 1:
        raise UsageError(f'--pairs must be at least 1, got {options.pairs}')
    if options.input_speed == 0.0 or not math.isfinite(options.input_speed):
        raise UsageError(f'--input-speed must be finite and non-zero, got '
                         f'{options.input_speed}')
    geometry = kin.Geometry.paper()  # shaper_sim's default geometry
    try:
        Loads(options.cutting_force, options.ram_friction,
              options.cutting_length).check_against(geometry.ram_stroke)
    except DynamicsError as error:
        raise UsageError(f'loads: {error}') from None
    for offset_mm in options.offsets_mm:
        try:
            kin.check_offset(geometry, offset_mm / 1e3, geometry.max_safe_offset)
        except kin.KinematicsError:
            raise UsageError(f'--offsets-mm: {offset_mm:g} mm is outside what shaper_sim '
                             f'accepts, |offset| <= {geometry.max_safe_offset * 1e3:g} mm'
                             ) from None


def record(options, folder, stop):
    """Run shaper_sim and mcap_recorder through the schedule; return the recording's path."""
    offsets = [value / 1e3 for value in options.offsets_mm]
    recording = os.path.join(folder, 'run.mcap')
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.update(env)
    sim_log = os.path.join(folder, 'shaper_sim.log')
    sim = _start('shaper_sim', [
        '-p', f'coupling_offset:={offsets[0]!r}', '-p', f'input_speed:={options.input_speed!r}',
        '-p', f'publish_rate:={float(options.publish_rate)!r}',
        '-p', f'offset_rate_limit:={float(options.offset_rate_limit)!r}',
        '-p', f'cutting_force:={float(options.cutting_force)!r}',
        '-p', f'ram_friction:={float(options.ram_friction)!r}',
        '-p', f'cutting_length:={float(options.cutting_length)!r}',
        '-p', f'drive:={options.drive}',
    ], sim_log, env)
    print(f'qrm_main: started shaper_sim (pid {sim.pid})', flush=True)
    recorder = None
    conductor = Conductor(stop)
    conductor.watch('shaper_sim', sim, sim_log)
    try:
        conductor.wait_for(conductor.sim_ready, START_TIMEOUT, 'shaper_sim to start')
        recorder_log = os.path.join(folder, 'mcap_recorder.log')
        # The recorder's topics and the linkage markers: the run then shows the machine
        # in Foxglove's 3D panel (config/foxglove_layout.json).
        topics = ', '.join(DEFAULT_TOPICS + [LINKAGE_MARKERS_TOPIC])
        recorder = _start('mcap_recorder', ['-p', f'output:={recording}',
                                            '-p', f'topics:=[{topics}]'], recorder_log, env)
        print(f'qrm_main: started mcap_recorder (pid {recorder.pid})', flush=True)
        conductor.watch('mcap_recorder', recorder, recorder_log)
        conductor.wait_for(conductor.recorder_subscribed, START_TIMEOUT,
                           'mcap_recorder to subscribe')
        _run_schedule(conductor, options, offsets)
    finally:
        try:
            conductor.let_start([(SIM_NODE_NAME, sim)] + (
                [(RECORDER_NODE_NAME, recorder)] if recorder is not None else []))
        except MainJobError as error:
            print(f'qrm_main: warning: {error}', file=sys.stderr)
        conductor.close()
        if recorder is not None and _stop(recorder) != 0:
            print(f'qrm_main: warning: mcap_recorder exited with {recorder.returncode}; see '
                  f'{folder}/mcap_recorder.log', file=sys.stderr)
        _stop(sim)
    return recording


def _run_schedule(conductor, options, offsets):
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


def report(recording, folder):
    """
    Analyse the recording; print the table, write results and figures into folder.

    Returns what the analysis lacks (lines; empty when the recording was read whole).
    """
    loaded = analysis.read_recording(recording)
    result = analysis.analyse(loaded)
    print()
    print(analysis.format_table(result))
    figures = analysis.write_outputs(  # all or none
        result, os.path.join(folder, 'results.csv'), os.path.join(folder, 'results.json'),
        os.path.join(folder, 'figures'))
    tour = _write_tour(result, os.path.join(folder, 'figures', TOUR_FILE))
    missing = analysis.incompleteness(loaded)
    for line in missing:
        print(f'qrm_main: warning: {line}', file=sys.stderr)
    print()
    print(f'qrm_main: recording  {recording}')
    print(f'qrm_main: results    {os.path.join(folder, "results.json")}, '
          f'{os.path.join(folder, "results.csv")}')
    for path in figures:
        print(f'qrm_main: figure     {path}')
    if tour:
        print(f'qrm_main: animation  {tour}')
    return missing


def _write_tour(result, path):
    """Write the linkage at a few offsets beside the figures; a failure only warns."""
    from qrm_ros.analysis import animation  # matplotlib: only once there is something to draw
    try:
        return animation.write_offset_tour(result, path)
    except (OSError, animation.AnimationError) as error:
        print(f'qrm_main: warning: no animation written: {error}', file=sys.stderr)
        return None


def run(options):
    """Run the experiment (options validated); return the run folder and what it lacks."""
    folder = os.path.join(options.output_dir,
                          datetime.now().strftime('qrm_%Y%m%d_%H%M%S_%f')[:-3])
    os.makedirs(folder)
    print(f'qrm_main: run folder {folder}', flush=True)
    try:
        with StopRequest() as stop:  # a stop signal ends the schedule; children stop cleanly
            recording = record(options, folder, stop)
    except Interrupted as error:
        raise Interrupted(error.signal_number, folder) from None
    missing = report(recording, folder)
    return folder, missing


def main(argv=None):
    parser = _parser()
    options = parser.parse_args(argv)
    try:
        validate(options)
    except UsageError as error:
        parser.error(str(error))  # exit code 2
    try:
        folder, missing = run(options)
    except Interrupted as error:
        print(f'qrm_main: {error}', file=sys.stderr)
        return 128 + error.signal_number
    except (MainJobError, analysis.AnalysisError) as error:
        print(f'qrm_main: error: {error}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C while analysing
        print('qrm_main: interrupted', file=sys.stderr)
        return 128 + signal.SIGINT
    if missing:  # analysed, but the recording was damaged or incomplete
        print(f'qrm_main: the results in {folder} cover only what was readable',
              file=sys.stderr)
        return EXIT_INCOMPLETE
    return 0


if __name__ == '__main__':
    sys.exit(main())
