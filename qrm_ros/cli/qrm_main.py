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

Its own ROS node, which sets the parameters and counts the pairs, is the Conductor
(qrm_ros.node.main_job.main_job_conductor).

Exit codes (qrm_ros.cli.exit_codes): 0 done, 1 a failure while running (a child that exits, a
time-out, a refused setting, an analysis error), 2 bad options (argparse), 3 analysed but the
recording was damaged or incomplete, 128 + the signal number when stopped by SIGINT (130,
Ctrl-C) or SIGTERM (143); the children are stopped cleanly either way.
"""

import argparse
from datetime import datetime
import math
import os
import re
import signal
import subprocess
import sys
import time
from typing import List, Optional

from qrm_ros import analysis
from qrm_ros.cli.main_job_offline import simulate_schedule
from qrm_ros.cli.main_job_plan import (check_start_up, SHORT_STROKE_MM, short_stroke_plan,
                                       start_up_parameters, UsageError)
from qrm_ros.cli.exit_codes import (EXIT_FAILURE, EXIT_INCOMPLETE, EXIT_INTERRUPTED, EXIT_OK,
                                    exit_code_for_signal)
from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics.chain import DynamicsError, Loads
from qrm_ros.core.common.names import (BRIDGE_DEFAULT_PORT, BRIDGE_NODE_NAME,
                                       BRIDGE_SERVING_PREFIX, DRIVES, LINKAGE_MARKERS_TOPIC,
                                       RECORDER_NODE_NAME, SIM_NODE_NAME)
from qrm_ros.node.main_job.main_job_conductor import (Conductor, Interrupted, MainJobError,
                                                      START_TIMEOUT)
from qrm_ros.node.recorder.recorder import DEFAULT_TOPICS
from qrm_ros.node.process.ros_process import StopRequest

# Both signs, and the offset of equal mid-stroke speeds (SR = 1, paper eq. 26: -r r1 / h).
UNITY_SPEED_RATIO_MM = kin.offset_for_speed_ratio(kin.Geometry.paper(), 1.0) * 1e3
DEFAULT_OFFSETS_MM = [-15.0, UNITY_SPEED_RATIO_MM, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0]
# Samples per input revolution by default (250 Hz at 60 rpm): at 100 the peak torque at
# 15 mm falls between samples beyond what the sampling supports to 1e-3 (the effort
# figures' bounds); at 250 every figure of the schedule is. Never below the node's own
# 100 Hz, nor above the 1 kHz it keeps up with (beyond, the analysis says what is lacking).
DEFAULT_SAMPLES_PER_REVOLUTION = 250.0
DEFAULT_RATES = (100.0, 1000.0)


def default_publish_rate(input_speed: float) -> float:
    """
    Return the publish rate [Hz] giving DEFAULT_SAMPLES_PER_REVOLUTION at input_speed.

    Rounded to 12 significant digits, so 60 rpm publishes at 250 Hz, not 249.99999999999997.
    """
    wanted = float(f'{DEFAULT_SAMPLES_PER_REVOLUTION * abs(input_speed) / (2 * math.pi):.12g}')
    return min(max(wanted, DEFAULT_RATES[0]), DEFAULT_RATES[1])


# Margin after the recorder's subscription appears before its data is surely flowing.
RECORDER_SETTLE_TIME = 0.5
CHILD_STOP_TIMEOUT = 15.0  # s, after SIGINT, before SIGKILL
# Beside the figures: one input revolution at each of a few offsets (qrm_ros.analysis.animation).
TOUR_FILE = 'offset_tour.gif'


def start_child(command_name, ros_arguments, log_path, env, arguments=()):
    """Start a package executable as its own process (works in a venv and under colcon)."""
    # Through the console script's entry point, so a stop during start-up is quiet too.
    command = [sys.executable, '-c', 'import sys; from qrm_ros.cli import entry_points; '
               f'sys.exit(entry_points.{command_name}())', *arguments,
               '--ros-args'] + ros_arguments
    with open(log_path, 'w') as log:  # the child keeps its own copy of the descriptor
        return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env,
                                start_new_session=True)


def stop_child(process, timeout=CHILD_STOP_TIMEOUT):
    """SIGINT (a clean finish), then SIGKILL if it hangs; return the exit code."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode


def _parameter_text(value):
    """Write a value as ``-p name:=value`` takes it (a float's repr keeps every bit)."""
    return value if isinstance(value, str) else repr(value)


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
    parser.add_argument('--publish-rate', type=float, default=None,
                        help='shaper_sim publish rate [Hz] (default: '
                        f'{DEFAULT_SAMPLES_PER_REVOLUTION:g} samples per input revolution, '
                        f'within {DEFAULT_RATES[0]:g}-{DEFAULT_RATES[1]:g} Hz: 250 Hz at 60 '
                        'rpm; the effort figures need that many to be supported to 1e-3 at '
                        'the largest offsets)')
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
    parser.add_argument('--short-stroke-mm', type=float, default=SHORT_STROKE_MM,
                        help='after the offset schedule, the paper\'s short-stroke experiment '
                        'at this ram stroke [mm]: offset 0, then the time ratio of the long '
                        'stroke held by the offset (default: %(default)s; 0: skip it)')
    parser.add_argument('--output-dir', default='runs',
                        help='folder for the run folder (default: runs)')
    parser.add_argument('--offline', action='store_true',
                        help='simulate the schedule offline (qrm_simulate), as fast as the CPU '
                        'allows, instead of running the nodes live over DDS')
    parser.add_argument('--live', action='store_true',
                        help='serve the run live to the Foxglove app (qrm_bridge beside it, on '
                             'this machine only); the address to open is printed')
    parser.add_argument('--live-port', type=int, default=BRIDGE_DEFAULT_PORT,
                        help='TCP port of the live view (default: '
                             f'{BRIDGE_DEFAULT_PORT}; 0: any free port)')
    return parser


def validate(options):
    """Refuse options the run cannot use, before anything starts (raises UsageError)."""
    if not 0 <= options.live_port <= 65535:
        raise UsageError(f'--live-port must be in 0-65535, got {options.live_port}')
    if options.offline and options.live:
        raise UsageError('--offline and --live exclude each other: an offline run has no live '
                         'graph to serve (play its recording with mcap_player beside qrm_bridge)')
    if options.pairs < 1:
        raise UsageError(f'--pairs must be at least 1, got {options.pairs}')
    if options.input_speed == 0.0 or not math.isfinite(options.input_speed):
        raise UsageError(f'--input-speed must be finite and non-zero, got '
                         f'{options.input_speed}')
    if options.publish_rate is None:
        options.publish_rate = default_publish_rate(options.input_speed)
    geometry = kin.Geometry.paper()  # shaper_sim's default geometry
    try:
        Loads(options.cutting_force, options.ram_friction,
              options.cutting_length).check_against(geometry.ram_stroke)
    except DynamicsError as error:
        raise UsageError(f'loads: {error}') from None
    if options.short_stroke_mm:
        # Refuses a stroke the node would not take.
        short_stroke_plan(options.short_stroke_mm, options.cutting_length)
    check_start_up(options)  # the rates and the rest of shaper_sim's start-up values
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
    parameters = [argument for name, value in start_up_parameters(options).items()
                  for argument in ('-p', f'{name}:={_parameter_text(value)}')]
    sim = start_child('shaper_sim', parameters, sim_log, env)
    print(f'qrm_main: started shaper_sim (pid {sim.pid})', flush=True)
    recorder = bridge = None
    conductor = Conductor(stop)
    conductor.watch('shaper_sim', sim, sim_log)
    try:
        conductor.wait_for(conductor.sim_ready, START_TIMEOUT, 'shaper_sim to start')
        if options.live:
            bridge = start_live_view(options.live_port, folder, env)
        recorder_log = os.path.join(folder, 'mcap_recorder.log')
        # The recorder's topics and the linkage markers: the run then shows the machine
        # in Foxglove's 3D panel (config/foxglove_layout.json).
        topics = ', '.join(DEFAULT_TOPICS + [LINKAGE_MARKERS_TOPIC])
        recorder = start_child('mcap_recorder', ['-p', f'output:={recording}',
                                                 '-p', f'topics:=[{topics}]'], recorder_log,
                               env)
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
        if recorder is not None and stop_child(recorder) != 0:
            print(f'qrm_main: warning: mcap_recorder exited with {recorder.returncode}; see '
                  f'{folder}/mcap_recorder.log', file=sys.stderr)
        stop_child(sim)
        if bridge is not None:
            stop_child(bridge)
    return recording


def start_live_view(port, folder, env, timeout=START_TIMEOUT):
    """
    Start qrm_bridge beside the run and print the address to open in the Foxglove app.

    A bridge that cannot start (the port is taken) only warns: the run goes on without it.
    """
    log_path = os.path.join(folder, BRIDGE_NODE_NAME + '.log')
    bridge = start_child(BRIDGE_NODE_NAME, [], log_path, env, ['--port', str(port)])
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and bridge.poll() is None:
        with open(log_path) as log:
            found = re.search(re.escape(BRIDGE_SERVING_PREFIX) + r'(ws://\S+)', log.read())
        if found:
            print(f'qrm_main: live view at {found.group(1)}: in the Foxglove app, Open '
                  'connection, Foxglove WebSocket, this address (layout: '
                  'config/foxglove_layout.json)', flush=True)
            return bridge
        time.sleep(0.05)
    stop_child(bridge)
    print(f'qrm_main: warning: no live view ({BRIDGE_NODE_NAME} did not start; see '
          f'{log_path})', file=sys.stderr, flush=True)
    return None


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
    if options.short_stroke_mm:
        _run_short_stroke(conductor, options, period, recording_since)


def _run_short_stroke(conductor, options, period, since):
    """Run the paper's short stroke: offset 0 (TR falls toward 1), then the long TR held."""
    stroke, workpiece, ratio = short_stroke_plan(options.short_stroke_mm,
                                                 options.cutting_length)
    timeout = (options.pairs + 3) * period + 20.0
    for what, settings, held in (
            ('offset 0', dict(coupling_offset=0.0, cutting_length=workpiece,
                              stroke_length=stroke), False),
            (f'time ratio {ratio:.4f} held', dict(time_ratio_target=ratio), True)):
        started = time.monotonic()
        conductor.set_parameters(**settings)
        conductor.wait_for(lambda: conductor.steady_pairs_at(
            None if held else 0.0, since, stroke_length=stroke,
            time_ratio_held=held) >= options.pairs, timeout,
            f'{options.pairs} steady stroke pairs at stroke {stroke} m, {what}')
        print(f'qrm_main: stroke {stroke * 1e3:.1f} mm, {what}: {options.pairs} steady stroke '
              f'pairs in {time.monotonic() - started:.1f} s', flush=True)


def report(recording, folder):
    """
    Analyse the recording; print the table, write results and figures into folder.

    The recording is streamed (analyse_file), and the figures and the tour read only what
    they draw: memory independent of the run's length. Returns what the analysis lacks
    (lines, as qrm_analyze says them; empty when every figure stands as printed).
    """
    result = analysis.analyse_file(recording, progress_stream=sys.stderr)
    print()
    print(analysis.format_table(result))
    figures = analysis.write_outputs(  # all or none
        result, os.path.join(folder, 'results.csv'), os.path.join(folder, 'results.json'),
        os.path.join(folder, 'figures'))
    tour = _write_tour(result, os.path.join(folder, 'figures', TOUR_FILE))
    lacking, unsupported = analysis.shortfalls(result)
    missing = lacking + unsupported
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
    # matplotlib: only once there is something to draw
    from qrm_ros.analysis import animation, animation_window
    try:
        return animation_window.write_window_tour(result, path)
    except (OSError, animation.AnimationError) as error:
        print(f'qrm_main: warning: no animation written: {error}', file=sys.stderr)
        return None


def run(options):
    """Run the experiment (options validated); return the run folder and what it lacks."""
    folder = os.path.join(options.output_dir,
                          datetime.now().strftime('qrm_%Y%m%d_%H%M%S_%f')[:-3])
    try:
        os.makedirs(folder)
    except OSError as error:  # a file, a read-only or virtual file system, a full disk
        raise UsageError(f'--output-dir {options.output_dir!r}: cannot make the run folder '
                         f'there ({error.strerror or error})') from None
    print(f'qrm_main: run folder {folder}', flush=True)
    try:
        with StopRequest() as stop:  # a stop signal ends the schedule; children stop cleanly
            if options.offline:
                recording = simulate_schedule(options, folder, stop)
            else:
                recording = record(options, folder, stop)
    except Interrupted as error:
        raise Interrupted(error.signal_number, folder) from None
    missing = report(recording, folder)
    return folder, missing


def main(argv: Optional[List[str]] = None) -> int:
    """Run the main job; return its exit code (bad options exit 2 through argparse)."""
    parser = _parser()
    options = parser.parse_args(argv)
    try:
        validate(options)
    except UsageError as error:
        parser.error(str(error))  # exit code 2
    try:
        folder, missing = run(options)
    except UsageError as error:
        parser.error(str(error))
    except Interrupted as error:
        print(f'qrm_main: {error}', file=sys.stderr)
        return exit_code_for_signal(error.signal_number)
    except (MainJobError, analysis.AnalysisError) as error:
        print(f'qrm_main: error: {error}', file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:  # Ctrl-C while analysing
        print('qrm_main: interrupted', file=sys.stderr)
        return EXIT_INTERRUPTED
    if missing:  # analysed, but something is lacking (the lines above say what)
        print(f'qrm_main: the results in {folder} are not complete (see the warnings above)',
              file=sys.stderr)
        return EXIT_INCOMPLETE
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
