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
``qrm_simulate [SCENARIO.yaml] -o RUN.mcap``: a shaper_sim run, offline, as fast as the CPU allows.

Writes the MCAP file mcap_recorder would write of the same run live
(qrm_ros.node.offline.offline_sim): the node itself ticked on a simulated clock, no DDS traffic
(its discovery is off). Without a scenario file, ``--duration`` and ``-p name:=value`` say it all.

Exit codes (qrm_ros.cli.exit_codes): 0 written; 1 a write error; 2 a bad option, scenario or
parameter value (one line says which and what is allowed; no file is left); 130 / 143
stopped by Ctrl-C / SIGTERM (the file holds what was simulated so far).
"""

import argparse
import os
import sys
from typing import Any, Dict, List, Optional, Sequence

from tqdm import tqdm
import yaml

from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK, exit_code_for_signal
from qrm_ros.core.common.names import SIM_NODE_NAME
from qrm_ros.node.offline.offline_sim import Simulation, SimulationSummary, summary_line
from qrm_ros.node.recorder.recorder import default_output_path, DEFAULT_TOPICS
from qrm_ros.node.process.ros_process import RCLError, rcl_error_text, StopRequest
from qrm_ros.node.offline.scenario import (load_scenario, Scenario, scenario_from_mapping,
                                           ScenarioError)
from qrm_ros.recording.mcap_run_file import (COMPRESSIONS, ConfigurationError, RecorderError,
                                             WriteFailed)
from rclpy.logging import LoggingSeverity, set_logger_level

__all__ = ['PROGRESS_MIN_DURATION', 'main', 'parse_parameter_options', 'simulate']

PROGRAM = 'qrm_simulate'
DISCOVERY_VARIABLE = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
# s of simulated time from which a terminal gets a progress bar (shorter runs take < 1 s).
PROGRESS_MIN_DURATION = 60.0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROGRAM,
        description='Simulate a shaper_sim scenario offline, as fast as the CPU allows, into '
                    'the MCAP file mcap_recorder would write of it live.',
        epilog='Exit status: 0 written; 1 a write error; 2 a bad option, scenario or parameter '
               '(no file is left); 130/143 stopped by Ctrl-C/SIGTERM (the file holds the run '
               'so far). Example: qrm_simulate --duration 60 -p coupling_offset:=0.01 '
               '-o run.mcap')
    parser.add_argument('scenario', nargs='?',
                        help='scenario file (YAML: parameters, duration, start_time, events)')
    parser.add_argument('-o', '--output', help='MCAP file to write (default: '
                        'runs/qrm_<date>_<time>.mcap); an existing file is never overwritten')
    parser.add_argument('--duration', type=float, metavar='SECONDS',
                        help='simulated time [s] (overrides the scenario\'s)')
    parser.add_argument('-p', '--parameter', action='append', default=[],
                        metavar='NAME:=VALUE', help='a start-up parameter of shaper_sim, as '
                        'with --ros-args -p (overrides the scenario\'s); repeatable')
    parser.add_argument('--start-time', type=float, metavar='SECONDS',
                        help='the simulated clock at the start [s] (default: the scenario\'s, '
                        'else 0)')
    parser.add_argument('--markers', action='store_true',
                        help='record the linkage markers too (as a recorder given '
                             'linkage_markers would)')
    parser.add_argument('--compression', choices=sorted(COMPRESSIONS), default='zstd',
                        help='chunk compression (default: %(default)s)')
    parser.add_argument('--progress', choices=('auto', 'always', 'never'), default='auto',
                        help='progress bar on stderr: auto = on a terminal for runs of '
                             f'{PROGRESS_MIN_DURATION:g} s or more (default: %(default)s)')
    parser.add_argument('--verbose', action='store_true',
                        help='show the node\'s INFO log lines (default: warnings only)')
    return parser


def parse_parameter_options(options: Sequence[str]) -> Dict[str, Any]:
    """Read ``name:=value`` options; values are YAML, as ROS reads ``-p``."""
    parameters = {}
    for option in options:
        name, separator, text = option.partition(':=')
        if not separator or not name:
            raise ScenarioError(f'-p {option!r}: write NAME:=VALUE, e.g. -p coupling_offset:=0.01')
        try:
            parameters[name] = yaml.safe_load(text)
        except yaml.YAMLError:
            raise ScenarioError(f'-p {option!r}: the value is not a YAML scalar') from None
    return parameters


def _scenario(args: argparse.Namespace) -> Scenario:
    parameters = parse_parameter_options(args.parameter)
    if args.scenario:
        return load_scenario(args.scenario, args.duration, parameters, args.start_time)
    return scenario_from_mapping({}, args.duration, parameters, args.start_time)


def simulate(scenario: Scenario, output: str, markers: bool = False,
             compression: str = 'zstd', progress: bool = False,
             stop: object = False) -> SimulationSummary:
    """
    Run a scenario into output (Simulation's errors pass through); return its summary.

    The node's discovery is off (ROS_AUTOMATIC_DISCOVERY_RANGE, read when the node is made,
    then put back): an offline run has nothing to do on the network.
    """
    before = os.environ.get(DISCOVERY_VARIABLE)
    os.environ[DISCOVERY_VARIABLE] = 'OFF'
    try:
        simulation = Simulation(scenario, output, topics=DEFAULT_TOPICS, markers=markers,
                                compression=compression)
    finally:
        if before is None:
            del os.environ[DISCOVERY_VARIABLE]
        else:
            os.environ[DISCOVERY_VARIABLE] = before
    if not progress:
        return simulation.run(stop=stop)
    with tqdm(total=round(scenario.duration), unit='s', desc='simulated', file=sys.stderr,
              bar_format='{l_bar}{bar}| {n:.0f}/{total:.0f} s [{elapsed}<{remaining}]'
              ) as bar:
        def advance(seconds: float) -> None:
            bar.update(seconds - bar.n)
        summary = simulation.run(advance, stop=stop)
        bar.update(bar.total - bar.n if not summary.stopped else 0)
    return summary


def main(argv: Optional[List[str]] = None) -> int:
    """Run qrm_simulate; return the exit status (see the module's docstring)."""
    args = _parser().parse_args(argv)
    try:
        scenario = _scenario(args)
    except ScenarioError as error:
        print(f'{PROGRAM}: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    output = args.output or default_output_path()
    progress = args.progress == 'always' or (
        args.progress == 'auto' and sys.stderr.isatty()
        and scenario.duration >= PROGRESS_MIN_DURATION)
    if not args.verbose:
        set_logger_level(SIM_NODE_NAME, LoggingSeverity.WARN)
    try:
        with StopRequest() as stop:
            summary = simulate(scenario, output, args.markers, args.compression, progress,
                               stop)
    except (ScenarioError, ConfigurationError, ValueError) as error:
        # A refused start-up value or event (the node's reason), an existing output.
        print(f'{PROGRAM}: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except WriteFailed as error:  # the file is removed: no recovery to point to
        print(f'{PROGRAM}: error: cannot write {error.path!r}: {error.reason}; no file was '
              'kept' + ('; free space on that disk (or raise the file size limit) or choose '
                        'another output (-o PATH)' if error.no_room else ''), file=sys.stderr)
        return EXIT_FAILURE
    except (RecorderError, RCLError) as error:
        text = rcl_error_text(error) if isinstance(error, RCLError) else error
        print(f'{PROGRAM}: error: {text}', file=sys.stderr)
        return EXIT_FAILURE
    print(summary_line(summary))
    if summary.stopped:
        print(f'{PROGRAM}: stopped after {summary.ticks} ticks; the file holds the run so far',
              file=sys.stderr)
        assert stop.signal_number is not None
        return exit_code_for_signal(stop.signal_number)
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
