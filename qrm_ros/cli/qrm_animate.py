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
``qrm_animate RUN.mcap -o OUT.gif|.mp4``: an animation of a recorded run (no ROS needed).

Analyses the run as qrm_analyze does (qrm_ros.analysis.streamed_run), then reads only the
span it animates and draws and writes the frames (qrm_ros.analysis.animation_window): memory
independent of the run's length. Exit status as qrm_analyze's: 0 written; 1
rendering or writing failed (nothing written); 2 bad options or nothing usable in the file
(one line says why); 3 written, but the recording was damaged or incomplete (stderr says
what was lost).
"""

import argparse
import sys
from typing import Optional, Sequence

from qrm_ros.analysis.animation import (AnimationError, check_output, check_rates, MAX_GIF_FPS,
                                        recorded_cutting_length)
from qrm_ros.analysis.animation_window import write_window_animation
from qrm_ros.analysis.linkage_figure import FRAME_SIZE
from qrm_ros.analysis.recorded_run import AnalysisError
from qrm_ros.analysis.report import incompleteness
from qrm_ros.analysis.streamed_run import analyse_file
from qrm_ros.cli.arguments import add_geometry_override_arguments, geometry_overrides
from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INCOMPLETE, EXIT_OK
from qrm_ros.recording.bag_reader import RunFileError


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='qrm_animate',
        description='Animate a recorded run: the linkage at each recorded joint state, with '
                    'ram velocity (and input torque when recorded), the offset in force and '
                    'the measured TR and SR of the steady segment.',
        epilog='Exit status: 0 written; 1 rendering or writing failed (nothing written); 2 '
               'bad options or nothing usable in the file; 3 written, but the recording was '
               'damaged or incomplete (stderr says what was lost).')
    parser.add_argument('run', help='recorded run (.mcap) from mcap_recorder')
    parser.add_argument('-o', '--output', required=True, metavar='OUT',
                        help='animation to write: OUT.gif (Pillow) or OUT.mp4 (needs the '
                             'imageio-ffmpeg package, extra qrm_ros[video])')
    parser.add_argument('--start', type=float, default=None, metavar='S',
                        help='start time [s] after the first joint state (default: 0)')
    parser.add_argument('--end', type=float, default=None, metavar='S',
                        help='end time [s] after the first joint state (default: the last)')
    parser.add_argument('--fps', type=float, default=25.0, metavar='N',
                        help='frames per second [1/s] of the animation, > 0; for a GIF 100/k '
                             f'for a whole k >= 2 (at most {MAX_GIF_FPS:g}) (default: 25)')
    parser.add_argument('--speed', type=float, default=1.0, metavar='X',
                        help='playback speed [-]: run seconds per animation second, > 0 '
                             '(default: 1)')
    add_geometry_override_arguments(parser)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run qrm_animate; return the exit status (see the module's docstring)."""
    args = _parser().parse_args(argv)
    overrides = geometry_overrides(args)
    try:
        check_rates(args.fps, args.speed, check_output(args.output))
        result = analyse_file(args.run, overrides, progress_stream=sys.stderr)
        count = write_window_animation(result, args.output, args.start, args.end, args.fps,
                                       args.speed, recorded_cutting_length(args.run),
                                       progress_stream=sys.stderr)
    except (AnimationError, AnalysisError, RunFileError) as error:
        print(f'qrm_animate: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as error:
        # the one output; error.filename may be its temporary name
        print(f'qrm_animate: error: cannot write {args.output}: '
              f'{error.strerror or error}; no animation was written', file=sys.stderr)
        return EXIT_FAILURE
    except Exception as error:  # noqa: B902 - ffmpeg, Pillow or matplotlib failing mid-way
        print(f'qrm_animate: error: writing {args.output} failed ({type(error).__name__}: '
              f'{error}); no animation was written', file=sys.stderr)
        return EXIT_FAILURE
    print(f'{args.output}: {count} frames, {FRAME_SIZE[0]} x {FRAME_SIZE[1]} px, '
          f'{args.fps:g} fps, {count / args.fps:.2f} s')
    lines = incompleteness(result.recording)
    for line in lines:
        print(f'qrm_animate: warning: {line}', file=sys.stderr)
    if lines:
        print('qrm_animate: warning: the animation covers only what was readable and usable',
              file=sys.stderr)
        return EXIT_INCOMPLETE
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
