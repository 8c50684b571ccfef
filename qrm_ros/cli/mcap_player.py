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
``mcap_player RUN.mcap``: a recording played back onto its ROS topics (node.player).

ROS arguments after ``--ros-args``. Exit codes (qrm_ros.cli.exit_codes): 0 played to the end
or stopped by Ctrl-C or SIGTERM; 1 a failure while running; 2 bad options or a file that is
no recording (one line says why); 3 played, but part of the file was damaged or refused by
DDS (bytes that do not fit their type; stderr says what was not played, as qrm_analyze
reports such files). A topic whose message type this environment cannot import is not
played, with a warning.
"""

import argparse
import math
import sys
import threading
from typing import Callable, List, Optional

from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INCOMPLETE, EXIT_OK
from qrm_ros.node.player.mcap_player import (DEFAULT_CLOCK_RATE, McapPlayer, OPTION_RANGES,
                                             PLAYER_NODE_NAME, PlaybackError, PlayOptions)
from qrm_ros.node.process.ros_process import (executor_kind, ExecutorChoiceError, init_rclpy,
                                              new_executor, own_arguments_of, RCLError,
                                              rcl_error_text, spin_until_stopped, StopRequest)
from qrm_ros.recording.bag_reader import open_run, Run, RunFileError
from rclpy.utilities import try_shutdown

__all__ = ['main', 'what_was_not_played']


def _in_range(field: str, unit: str = '') -> Callable[[str], float]:
    """Return an argparse type taking a number within OPTION_RANGES[field] (unit: ' s')."""
    low, high = OPTION_RANGES[field]

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(
                f'{text}{unit} is not a number in [{low:.10g}, {high:.10g}]{unit}')
        return value
    return parse


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PLAYER_NODE_NAME,
        description='Play a recorded run (MCAP: mcap_recorder, qrm_simulate, ros2 bag record) '
                    'back onto its topics, as the recorded bytes, with the recorded QoS and '
                    'timing. Services: ~/pause, ~/resume, ~/toggle_paused, ~/play_next '
                    '(std_srvs/Trigger).',
        epilog='Exit status: 0 played (or stopped by Ctrl-C/SIGTERM); 1 a failure; 2 bad '
               'options or not a recording; 3 played, but parts were damaged or refused by DDS.')
    parser.add_argument('run', help='recorded run (.mcap)')
    parser.add_argument('--rate', type=_in_range('rate'), default=1.0,
                        help='playback speed factor (default: %(default)s)')
    parser.add_argument('--loop', action='store_true', help='play again from the start, '
                        'until stopped')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC',
                        help='play only these topics (default: all)')
    parser.add_argument('--start-offset', type=_in_range('start_offset', ' s'), default=0.0,
                        metavar='SECONDS',
                        help='start this far into the recording [s]')
    parser.add_argument('--delay', type=_in_range('delay', ' s'), default=0.0, metavar='SECONDS',
                        help='wait this long before the first message, so that late '
                             'subscribers are matched [s]')
    parser.add_argument('--clock', type=_in_range('clock_rate', ' Hz'), nargs='?',
                        const=DEFAULT_CLOCK_RATE,
                        metavar='HZ', help='publish /clock from the recorded time at HZ '
                        f'(default when given: {DEFAULT_CLOCK_RATE:g} Hz)')
    parser.add_argument('--start-paused', action='store_true',
                        help='start paused (~/resume or ~/play_next go on)')
    return parser


def what_was_not_played(run: Run, player: McapPlayer) -> List[str]:
    """Lines saying what of the file was not played; empty when all of it was."""
    lines = []
    if run.problem:
        lines.append(f'{run.path} is damaged or truncated: {run.problem}')
    for loss in player.losses:
        count = 'an unknown number of' if loss.messages is None else f'{loss.messages}'
        lines.append(f'{count} messages not played: {loss.reason}')
    for topic, why in sorted(player.skipped.items()):
        lines.append(f'{topic} not played: {why}')
    for topic, (count, why) in sorted(player.refused.items()):
        lines.append(f'{count} messages on {topic} not played: DDS refused them ({why}); their '
                     'bytes do not fit the type')
    return lines


class _Finished:
    """Truthy once the stop request came or the playback ended (stops the service thread)."""

    def __init__(self, stop: StopRequest) -> None:
        self.stop = stop
        self.done = False

    def __bool__(self) -> bool:
        return self.done or bool(self.stop)


def _error(text: str) -> None:
    print(f'{PLAYER_NODE_NAME}: error: {text}', file=sys.stderr)


def _play(argv: List[str], args: argparse.Namespace, run: Run) -> int:
    try:
        init_rclpy(argv)
    except RCLError as error:
        _error(rcl_error_text(error))
        return EXIT_BAD_INPUT
    options = PlayOptions(args.rate, args.loop, args.topics, args.start_offset, args.delay,
                          args.clock, args.start_paused)
    player = executor = thread = None
    try:
        with StopRequest() as stop:
            finished = _Finished(stop)
            try:
                executor = new_executor(executor_kind())
                player = McapPlayer(run, options)
            except (PlaybackError, ExecutorChoiceError) as error:
                print(f'{PLAYER_NODE_NAME}: error: {error}', file=sys.stderr)
                return EXIT_BAD_INPUT
            executor.add_node(player)
            thread = threading.Thread(target=spin_until_stopped, args=(executor, finished),
                                      daemon=True)
            thread.start()
            player.play(stop)
            finished.done = True
            thread.join()
    except RCLError as error:
        _error(rcl_error_text(error))
        return EXIT_FAILURE
    finally:
        if executor is not None:
            executor.shutdown()
        if player is not None:
            player.destroy_node()
        try_shutdown()
    timing = player.timing_summary()
    print(f'played {player.published} messages on {len(player.topics)} topics'
          + (f'; {timing}' if timing else ''))
    for line in what_was_not_played(run, player):
        print(f'{PLAYER_NODE_NAME}: warning: {line}', file=sys.stderr)
    # Damage, or messages DDS refused, make the playback incomplete; a type this environment
    # lacks only warns.
    return EXIT_INCOMPLETE if run.problem or player.losses or player.refused else EXIT_OK


def main(argv: Optional[List[str]] = None) -> int:
    """
    Play a run; return the exit status (see the module's docstring).

    argv: the whole command line, program name first, as sys.argv (None: sys.argv).
    """
    command_line = sys.argv if argv is None else argv
    own_arguments = own_arguments_of(command_line, _error)
    if own_arguments is None:
        return EXIT_BAD_INPUT
    args = _parser().parse_args(own_arguments)
    try:
        run = open_run(args.run)
    except RunFileError as error:
        print(f'{PLAYER_NODE_NAME}: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    return _play(command_line, args, run)


if __name__ == '__main__':
    sys.exit(main())
