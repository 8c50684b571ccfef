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
``qrm_analyze RUN.mcap``: measured time and speed ratios per offset in a run, against theory.

Streams the run through the analysis in bounded memory (qrm_ros.analysis.streamed_run:
read, check, decode, segment and measure block by block) and prints the table; writes CSV,
JSON and the paper's figures when asked (qrm_ros.analysis.report, qrm_ros.analysis.figures).

Exit status: 0 analysed, complete; 1 failure at run time (an output could not be written;
no output file is left half written); 2 bad usage or an input that cannot be analysed (one
line on stderr says why); 3 analysed, but incomplete (stderr says what was lost).
"""

import argparse
import sys
from typing import Optional, Sequence

from qrm_ros.analysis.recorded_run import AnalysisError
from qrm_ros.analysis.report import format_table, incompleteness, write_outputs
from qrm_ros.analysis.streamed_run import analyse_file
from qrm_ros.cli.arguments import add_geometry_override_arguments, geometry_overrides
from qrm_ros.cli.exit_codes import (EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INCOMPLETE,
                                    EXIT_INTERRUPTED, EXIT_OK)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='qrm_analyze',
        description='Measure time ratio and speed ratio per offset in a recorded run and '
                    'compare them with the closed form.',
        epilog='Exit status: 0 analysed, complete; 1 an output could not be written; 2 bad '
               'usage or a file that cannot be analysed; 3 analysed, but incomplete (damaged '
               'or truncated file, unusable messages: stderr says what was lost).')
    parser.add_argument('run', help='recorded run (.mcap) from mcap_recorder')
    parser.add_argument('--csv', metavar='FILE', help='write the per-segment table as CSV')
    parser.add_argument('--json', metavar='FILE', help='write the results as JSON')
    parser.add_argument('--plot', metavar='DIR', help='write the figures (PNG) into DIR')
    add_geometry_override_arguments(parser)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run qrm_analyze; return the exit status (see the module's docstring)."""
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:
        print('qrm_analyze: interrupted; no output file was written', file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # a last resort: a bug must not print a traceback either
        print(f'qrm_analyze: error: internal failure ({type(error).__name__}: {error}); '
              'please report it with the file', file=sys.stderr)
        return EXIT_FAILURE


def _main(args: argparse.Namespace) -> int:
    overrides = geometry_overrides(args)
    try:
        result = analyse_file(args.run, overrides)
    except AnalysisError as error:
        print(f'qrm_analyze: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    recording = result.recording
    print(format_table(result))
    try:
        figure_paths = write_outputs(result, args.csv, args.json, args.plot)
    except OSError as error:
        print(f'qrm_analyze: error: cannot write {error.filename or "an output"}: '
              f'{error.strerror or error}; no output file was written', file=sys.stderr)
        return EXIT_FAILURE
    for path in figure_paths:
        print(f'figure: {path}')
    lines = incompleteness(recording)
    for line in lines:
        print(f'qrm_analyze: warning: {line}', file=sys.stderr)
    if lines:
        print('qrm_analyze: warning: the figures above cover only what was readable and '
              'usable', file=sys.stderr)
        return EXIT_INCOMPLETE
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
