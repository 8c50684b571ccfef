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

``qrm_analyze RUN.mcap RUN.mcap DIR ... [--output-dir OUT] [--jobs N | --scheduler URL]``: a
fleet, each file analysed on its own in parallel (qrm_ros.analysis.fleet), one report over all;
the exit status is the worst file's.

Streams the run through the analysis in bounded memory (qrm_ros.analysis.streamed_run:
read, check, decode, segment and measure block by block) and prints the table; writes CSV,
JSON and the paper's figures when asked (qrm_ros.analysis.report, qrm_ros.analysis.figures).

Exit status: 0 analysed, complete; 1 failure at run time (an output could not be written;
no output file is left half written); 2 bad usage or an input that cannot be analysed (one
line on stderr says why); 3 analysed, but incomplete (stderr says what was lost), or sampled
too coarsely to support a figure to 1e-3 (stderr names the figure and its bound).
"""

import argparse
import os
import signal
import sys
from typing import Any, List, Optional, Sequence

from qrm_ros.analysis import fleet
from qrm_ros.analysis.dask_scheduler import scheduler_address_problem, SchedulerError
from qrm_ros.analysis.recorded_run import AnalysisError, usable_cores
from qrm_ros.analysis.report import format_table, shortfalls, write_outputs
from qrm_ros.analysis.streamed_run import analyse_file
from qrm_ros.cli.arguments import add_geometry_override_arguments, geometry_overrides
from qrm_ros.cli.exit_codes import (EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INCOMPLETE,
                                    EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='qrm_analyze',
        description='Measure time ratio and speed ratio per offset in a recorded run and '
                    'compare them with the closed form.',
        epilog='Exit status: 0 analysed, complete; 1 an output could not be written; 2 bad '
               'usage or a file that cannot be analysed; 3 analysed, but incomplete (damaged '
               'or truncated file, unusable messages: stderr says what was lost) or sampled '
               'too coarsely to support a figure to 1e-3 (stderr says which).')
    parser.add_argument('run', nargs='+',
                        help='recorded run (.mcap) from mcap_recorder; several runs, or folders '
                             '(searched for .mcap files), make a fleet')
    parser.add_argument('--csv', metavar='FILE', help='write the per-segment table as CSV')
    parser.add_argument('--json', metavar='FILE', help='write the results as JSON')
    parser.add_argument('--plot', metavar='DIR', help='write the figures (PNG) into DIR')
    parser.add_argument('--output-dir', metavar='DIR',
                        help='fleet: write DIR/<file stem>/results.json and results.csv per run, '
                             'and DIR/fleet.json, fleet.csv and the TR error figure')
    parser.add_argument('--jobs', type=int, metavar='N',
                        help='fleet: analyse N files at a time in local processes (default: '
                             'one per usable core)')
    parser.add_argument('--scheduler', metavar='URL',
                        help='fleet: send the files to the Dask cluster whose scheduler is at '
                             'URL (e.g. tcp://HOST:8786); its workers must be able to read '
                             'the files by the paths given')
    add_geometry_override_arguments(parser)
    return parser


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C's KeyboardInterrupt would be: the same clean stop."""


def _raise_terminated(signal_number: int, frame: Any) -> None:
    del signal_number, frame
    raise _Terminated()


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run qrm_analyze; return the exit status (see the module's docstring)."""
    args = _parser().parse_args(argv)
    # SIGTERM stops as Ctrl-C does: the pool's workers (or the cluster's tasks) with it,
    # nothing half-written; the default would end this process alone, its workers going on.
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        return _main(args)
    except KeyboardInterrupt as stop:
        print('qrm_analyze: interrupted; no output file was written', file=sys.stderr)
        return EXIT_TERMINATED if isinstance(stop, _Terminated) else EXIT_INTERRUPTED
    except Exception as error:  # a last resort: a bug must not print a traceback either
        print(f'qrm_analyze: error: internal failure ({type(error).__name__}: {error}); '
              'please report it with the file', file=sys.stderr)
        return EXIT_FAILURE
    finally:
        signal.signal(signal.SIGTERM, previous)


def _is_fleet(args: argparse.Namespace) -> bool:
    return (len(args.run) > 1 or os.path.isdir(args.run[0]) or args.output_dir is not None
            or args.jobs is not None or args.scheduler is not None)


def _main(args: argparse.Namespace) -> int:
    if _is_fleet(args):
        return _fleet_main(args)
    (args.run,) = args.run
    overrides = geometry_overrides(args)
    try:
        result = analyse_file(args.run, overrides, progress_stream=sys.stderr)
    except AnalysisError as error:
        print(f'qrm_analyze: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    print(format_table(result))
    try:
        figure_paths = write_outputs(result, args.csv, args.json, args.plot)
    except OSError as error:
        print(f'qrm_analyze: error: cannot write {error.filename or "an output"}: '
              f'{error.strerror or error}; no output file was written', file=sys.stderr)
        return EXIT_FAILURE
    for path in figure_paths:
        print(f'figure: {path}')
    lines, unsupported = shortfalls(result)
    for line in lines + unsupported:
        print(f'qrm_analyze: warning: {line}', file=sys.stderr)
    if lines:
        print('qrm_analyze: warning: the figures above cover only what was readable and '
              'usable', file=sys.stderr)
    return EXIT_INCOMPLETE if lines or unsupported else EXIT_OK


# A fleet's status is its worst file's: a failure over a refusal over an incomplete file.
_SEVERITY = [EXIT_OK, EXIT_INCOMPLETE, EXIT_BAD_INPUT, EXIT_FAILURE]
_EXIT_OF_STATUS = {fleet.COMPLETE: EXIT_OK, fleet.INCOMPLETE: EXIT_INCOMPLETE,
                   fleet.REFUSED: EXIT_BAD_INPUT, fleet.FAILED: EXIT_FAILURE}


def _refusal(args: argparse.Namespace) -> Optional[str]:
    """Say what is wrong with a fleet's options, or None."""
    single = [f'--{name}' for name in ('csv', 'json', 'plot') if getattr(args, name)]
    if single:
        return (f'{", ".join(single)} take one run; for several, --output-dir DIR writes each '
                "run's results under DIR")
    if args.jobs is not None and args.jobs < 1:
        return f'--jobs must be a whole number of processes >= 1, got {args.jobs}'
    if args.scheduler is not None and args.jobs is not None:
        return '--jobs is for local processes; the --scheduler\'s cluster has its own workers'
    if args.scheduler is not None and (problem := scheduler_address_problem(args.scheduler)):
        return problem
    missing = [path for path in args.run if not os.path.exists(path)]
    if missing:
        return f'run file or folder {missing[0]!r} does not exist'
    if args.output_dir is not None and os.path.exists(args.output_dir) and not os.path.isdir(
            args.output_dir):
        return f'--output-dir {args.output_dir!r} is a file, not a folder'
    return None


def _fleet_results(args: argparse.Namespace, paths: List[str]) -> List[fleet.FileResult]:
    """Analyse the fleet where asked, with one progress bar over the files."""
    from tqdm import tqdm
    overrides = geometry_overrides(args)
    jobs = usable_cores() if args.jobs is None else args.jobs
    if args.scheduler is not None:
        results = fleet.run_on_cluster(paths, overrides, args.scheduler)
    elif jobs == 1 or len(paths) == 1:
        results = fleet.run_serially(paths, overrides)
    else:
        results = fleet.run_in_pool(paths, overrides, jobs)
    with tqdm(total=len(paths), unit='file', desc='analysing', file=sys.stderr,
              disable=not sys.stderr.isatty(), leave=False) as bar:
        return fleet.in_file_order(paths, results, lambda: bar.update(1))


def _fleet_main(args: argparse.Namespace) -> int:
    refusal = _refusal(args)
    paths = fleet.find_runs(args.run) if refusal is None else []
    if refusal is None and not paths:
        refusal = f'no {fleet.RUN_SUFFIX} files in {", ".join(args.run)}'
    if refusal is not None:
        print(f'qrm_analyze: error: {refusal}', file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        results = _fleet_results(args, paths)
    except SchedulerError as error:  # said before any file is sent: the address, not a run
        print(f'qrm_analyze: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as error:  # the cluster went away while it worked, say
        print(f'qrm_analyze: error: the fleet could not be analysed: {error}', file=sys.stderr)
        return EXIT_FAILURE
    document = fleet.fleet_document(results)
    print(fleet.format_fleet_table(document))
    for result in results:
        if result.status in (fleet.REFUSED, fleet.FAILED):
            print(f'qrm_analyze: error: {result.problem}', file=sys.stderr)
        elif result.analysis is not None:
            for line in sum(shortfalls(result.analysis), []):
                print(f'qrm_analyze: warning: {line}', file=sys.stderr)
    if args.output_dir is not None:
        try:
            os.makedirs(args.output_dir, exist_ok=True)
            written = fleet.write_fleet_report(results, document, args.output_dir)
        except OSError as error:
            print(f'qrm_analyze: error: cannot write {error.filename or "an output"}: '
                  f'{error.strerror or error}; no fleet report was written', file=sys.stderr)
            return EXIT_FAILURE
        print(f'fleet report: {written[-3]}, {written[-2]}; figure: {written[-1]}')
    return max((_EXIT_OF_STATUS[result.status] for result in results), key=_SEVERITY.index)


if __name__ == '__main__':
    sys.exit(main())
