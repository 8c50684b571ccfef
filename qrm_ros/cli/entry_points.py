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
The console scripts' entry points: a stop signal never prints a traceback.

Importing a command's module (rclpy, numpy, scipy) takes a moment, longer on a loaded
machine; a Ctrl-C or a launch system's SIGTERM in that moment would otherwise end in a
KeyboardInterrupt traceback (or a bare kill). So each script first makes both signals a quiet
exit, then imports its module; the long-running commands replace these handlers with their
own clean-stop handling (qrm_ros.node.process.ros_process) once they are up.

A stop while starting exits as a stop at any other moment would: 128 + the signal's number
for a batch command (so that ``qrm_simulate … && next`` does not go on), 0 for the nodes,
whose stop is a clean finish. A command started with SIGINT ignored (``cmd &`` from a
script) has Ctrl-C's default restored, as the long-running ones do.
"""

import importlib
import os
import signal
import sys
from typing import List

from qrm_ros.cli.exit_codes import EXIT_INTERRUPTED, EXIT_OK, exit_code_for_signal

__all__ = ['mcap_recorder', 'qrm_analyze', 'qrm_animate', 'qrm_bridge', 'qrm_design', 'qrm_main',
           'qrm_urdf', 'run_command', 'shaper_sim', 'STOP_IS_A_FINISH', 'qrm_simulate',
           'mcap_player']


_STOP_REQUESTS: List[int] = []  # the stop signals received while starting
# The commands for which a stop is a clean finish (exit 0) at any moment: the nodes.
STOP_IS_A_FINISH = ('qrm_ros.cli.shaper_sim', 'qrm_ros.cli.mcap_recorder',
                    'qrm_ros.cli.mcap_player', 'qrm_ros.cli.qrm_bridge')


def _stop_status(module_name: str, signal_number: int) -> int:
    """How a command exits on a stop: 0 for a node, 128 + the signal's number for the rest."""
    return EXIT_OK if module_name in STOP_IS_A_FINISH else exit_code_for_signal(signal_number)


def _ament_index_of_this_python() -> None:
    """
    Point the ament index at this Python's prefix when nothing else does.

    The ROS 2 wheels install their share folders (message definitions, the package index)
    into the environment they are installed in; a sourced ROS install sets AMENT_PREFIX_PATH
    itself, a plain virtual environment does not, and the recorder's schemas need it.
    """
    if not os.environ.get('AMENT_PREFIX_PATH') and os.path.isdir(
            os.path.join(sys.prefix, 'share', 'ament_index')):
        os.environ['AMENT_PREFIX_PATH'] = sys.prefix


def run_command(module_name: str) -> int:
    """Import the command's module with stop signals made quiet, then run its main."""
    _ament_index_of_this_python()

    def stopped_while_starting(signal_number, frame):
        del frame
        _STOP_REQUESTS.append(signal_number)
        # Nothing was started: nothing to undo.
        raise SystemExit(_stop_status(module_name, signal_number))
    previous = {number: signal.signal(number, stopped_while_starting)
                for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        module = importlib.import_module(module_name)
    except Exception:
        # The SystemExit raised inside a C extension's initialisation (scipy's, say) comes
        # out as its ImportError: still the stop asked for, not a failure to report.
        if _STOP_REQUESTS:
            raise SystemExit(_stop_status(module_name, _STOP_REQUESTS[0])) from None
        raise
    for number, handler in previous.items():
        # An ignored SIGINT (a background job of a script) gets Ctrl-C's default back.
        signal.signal(number, signal.default_int_handler
                      if number == signal.SIGINT and handler == signal.SIG_IGN else handler)
    try:
        return module.main()
    except KeyboardInterrupt:  # a batch command (analysis, design table) cut short
        print(f'{module_name.rsplit(".", 1)[-1]}: interrupted', file=sys.stderr)
        return EXIT_INTERRUPTED


def shaper_sim():
    return run_command('qrm_ros.cli.shaper_sim')


def mcap_recorder():
    return run_command('qrm_ros.cli.mcap_recorder')


def qrm_analyze():
    return run_command('qrm_ros.cli.qrm_analyze')


def qrm_animate():
    return run_command('qrm_ros.cli.qrm_animate')


def qrm_design():
    return run_command('qrm_ros.cli.qrm_design')


def qrm_main():
    return run_command('qrm_ros.cli.qrm_main')


def qrm_urdf():
    return run_command('qrm_ros.cli.qrm_urdf')


def qrm_simulate():
    return run_command('qrm_ros.cli.qrm_simulate')


def mcap_player():
    return run_command('qrm_ros.cli.mcap_player')


def qrm_bridge():
    return run_command('qrm_ros.cli.qrm_bridge')
