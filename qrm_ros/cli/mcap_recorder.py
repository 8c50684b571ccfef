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
The ``mcap_recorder`` command: records a shaper_sim run (qrm_ros.node.recorder.recorder) to MCAP.

``mcap_recorder --ros-args -p output:=runs/run.mcap`` records until Ctrl-C or SIGTERM;
``mcap_recorder --recover BROKEN.mcap FIXED.mcap`` finishes a file left by SIGKILL, a power
loss or a full disk (``mcap_recover``). It loads no numerical library: it starts recording
as fast as a bare subscriber.

Exit codes (qrm_ros.cli.exit_codes): 0 done, 1 a failure while running (a write error, a
full disk), 2 a usage or configuration error (bad arguments or parameters, an existing
output file).
"""

import argparse
import sys
from typing import List, Optional

from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK
from qrm_ros.core.common.names import RECORDER_NODE_NAME
from qrm_ros.node.recorder.recorder import Recorder
from qrm_ros.node.process.ros_process import (ExecutorChoiceError, own_arguments_of, run_node,
                                              start_rclpy)
from qrm_ros.recording.mcap_recover import recover_command
from qrm_ros.recording.mcap_run_file import ConfigurationError, RecorderError
from rclpy.exceptions import NameValidationException, ParameterException

__all__ = ['main']


def _options(argv):
    parser = argparse.ArgumentParser(
        prog='mcap_recorder',
        description='Record a shaper_sim run to MCAP (ROS parameters after --ros-args), or '
                    'finish a recording left unfinished.',
        epilog='Recording: mcap_recorder --ros-args -p output:=runs/run.mcap')
    parser.add_argument('--recover', nargs=2, metavar=('BROKEN', 'FIXED'),
                        help='rewrite what is readable in BROKEN (left by SIGKILL, a power '
                             'loss or a full disk) into a new, finished file FIXED')
    return parser, parser.parse_args(argv)


def _error(text):
    print(f'{RECORDER_NODE_NAME}: error: {text}', file=sys.stderr, flush=True)


def _record(argv):
    """Run the recorder node until SIGINT/SIGTERM; return the exit code."""
    if not start_rclpy(argv, _error):
        return EXIT_BAD_INPUT

    def finish(recorder, executor):
        recorder.drain(executor)
        recorder.finish()
    code = run_node(Recorder, _error, {
        (ConfigurationError, ExecutorChoiceError, ParameterException,
         NameValidationException): EXIT_BAD_INPUT,
        RecorderError: EXIT_FAILURE}, on_stop=finish)
    return EXIT_OK if code is None else code


def main(argv: Optional[List[str]] = None) -> int:
    """
    Record (ROS arguments after --ros-args) or, with --recover, finish a broken file.

    argv: the whole command line, program name first, as sys.argv (None: sys.argv).
    """
    command_line = sys.argv if argv is None else argv
    own_arguments = own_arguments_of(command_line, _error)
    if own_arguments is None:
        return EXIT_BAD_INPUT
    parser, options = _options(own_arguments)
    if options.recover:
        broken, fixed = options.recover
        return recover_command(broken, fixed, parser.error)
    return _record(argv)


if __name__ == '__main__':
    sys.exit(main())
