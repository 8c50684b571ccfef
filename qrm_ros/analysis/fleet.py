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
A fleet of recordings: each analysed on its own, in parallel, and one report over them all.

Each file goes through the streamed analysis (qrm_ros.analysis.streamed_run) in a worker:
serially, in a pool of local processes, or on a Dask cluster (``dask.distributed``; the
workers read the files by the paths given, so those must be readable where they run). A
worker returns the file's Analysis, or why it could not be analysed; the fleet report has
one row per recording (its geometry and drive from its metadata, duration, segments, stroke
pairs, worst TR and SR errors, losses, status), in the order of the files, whatever order
the workers finish in: the same report from any of the three.
"""

import csv
import json
import math
import multiprocessing
import os
import signal
import sys
import threading
from typing import Any, Callable, Dict, Iterable, Iterator, List, NamedTuple, Optional, Sequence

from qrm_ros.analysis.dask_scheduler import connect_to_scheduler
from qrm_ros.analysis.measurement import Analysis, finite_or_none
from qrm_ros.analysis.recorded_drive import drive_values
from qrm_ros.analysis.recorded_run import AnalysisError
from qrm_ros.analysis.report import shortfalls, write_csv_to, write_json_to
from qrm_ros.analysis.streamed_run import analyse_file
from qrm_ros.core import kinematics as kin
from qrm_ros.recording.atomic_files import staged_outputs

RUN_SUFFIX = '.mcap'
# A file's status in the fleet: analysed whole, analysed but incomplete (data lost or left
# out, theory missing, figures the sampling cannot support: report.shortfalls, said in its
# row), refused (cannot be analysed: the reason is in its row), or failed (an unexpected
# error).
COMPLETE, INCOMPLETE, REFUSED, FAILED = 'complete', 'incomplete', 'refused', 'failed'
FLEET_FIELDS = ('file', 'status', 'problem', *kin.Geometry.field_names(), 'drive', 'duration',
                'samples', 'segments', 'stroke_pairs', 'worst_time_ratio_error',
                'worst_speed_ratio_error', 'lost_messages', 'losses')
FLEET_FIGURE = 'fleet_time_ratio_error.png'


class FileResult(NamedTuple):
    """What a worker gives back for one file: its analysis, or why there is none."""

    path: str
    status: str
    analysis: Optional[Analysis]
    problem: Optional[str]  # the refusal, failure or shortfalls, one line; None: complete


def find_runs(paths: Sequence[str]) -> List[str]:
    """Return the run files named or found (recursively, sorted) in the folders named."""
    found: List[str] = []
    for path in paths:
        if os.path.isdir(path):
            for folder, subfolders, files in os.walk(path):
                subfolders.sort()
                found += [os.path.join(folder, name) for name in sorted(files)
                          if name.endswith(RUN_SUFFIX)]
        else:
            found.append(path)
    return found


def output_names(paths: Sequence[str]) -> List[str]:
    """Return a folder name per file: its stem, made unique with -2, -3... in file order."""
    names: List[str] = []
    for path in paths:
        stem = os.path.splitext(os.path.basename(path))[0] or 'run'
        name, number = stem, 1
        while name in names:
            number += 1
            name = f'{stem}-{number}'
        names.append(name)
    return names


def analyse_run(path: str, geometry_overrides: Optional[Dict[str, Optional[float]]] = None
                ) -> FileResult:
    """Analyse one file of the fleet (a worker's task); never raises for a bad file."""
    try:
        analysis = analyse_file(path, geometry_overrides, progress_stream=None)
    except AnalysisError as error:
        return FileResult(path, REFUSED, None, str(error))
    except Exception as error:  # noqa: B902 - one bad file must not stop the fleet
        return FileResult(path, FAILED, None, f'internal failure ({type(error).__name__}: '
                                              f'{error})')
    lacking = sum(shortfalls(analysis), [])  # the single file's rule: exit 3 if any
    return FileResult(path, INCOMPLETE if lacking else COMPLETE, analysis,
                      '; '.join(lacking) or None)


def _ignore_interrupts() -> None:
    """Leave Ctrl-C to the parent, which stops the pool (a worker would die mid-pickle)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # The pool ends its workers with SIGTERM: not the parent's handler (a forked worker
    # inherits it), which would raise inside the worker's loop.
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _analyse_task(task: Any) -> Any:
    index, path, overrides = task
    return index, analyse_run(path, overrides)


def run_serially(paths: Sequence[str], overrides: Optional[Dict[str, Optional[float]]]
                 ) -> Iterator[FileResult]:
    """Analyse the files one after the other, in this process."""
    for path in paths:
        yield analyse_run(path, overrides)


def start_method() -> str:
    """
    Return how the pool starts its workers: 'fork' when no other thread may hold a lock.

    A forked worker starts at once with the analysis already imported (a spawned one spends
    about 0.6 s of CPU importing it again). A process with another Python thread (a Dask
    client's, a progress bar's monitor) or with ROS loaded (DDS's threads) spawns its
    workers instead. The numerical libraries' own thread pools (OpenBLAS's) are made safe
    to fork by the libraries themselves.
    """
    quiet = threading.active_count() == 1 and 'rclpy' not in sys.modules
    return 'fork' if quiet and 'fork' in multiprocessing.get_all_start_methods() else 'spawn'


def run_in_pool(paths: Sequence[str], overrides: Optional[Dict[str, Optional[float]]],
                jobs: int) -> Iterator[FileResult]:
    """
    Analyse the files in a pool of jobs local processes; yield as they finish.

    The workers start now (start_method), before the caller shows anything; leaving the
    iteration early (Ctrl-C in the parent, say) terminates every worker.
    """
    context = multiprocessing.get_context(start_method())
    pool = context.Pool(min(jobs, len(paths)), initializer=_ignore_interrupts)
    tasks = [(index, path, overrides) for index, path in enumerate(paths)]
    return _pool_results(pool, tasks)


def _pool_results(pool: Any, tasks: List[Any]) -> Iterator[FileResult]:
    try:
        for _, result in pool.imap_unordered(_analyse_task, tasks):
            yield result
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def run_on_cluster(paths: Sequence[str], overrides: Optional[Dict[str, Optional[float]]],
                   scheduler: str) -> Iterator[FileResult]:
    """
    Analyse the files on the Dask cluster whose scheduler is at scheduler (tcp://HOST:PORT).

    Leaving the iteration early cancels the tasks not yet done. SchedulerError
    (dask_scheduler) when the scheduler cannot be reached or does not speak Dask.
    """
    from distributed import as_completed
    with connect_to_scheduler(scheduler) as client:
        futures = client.map(analyse_run, list(paths), geometry_overrides=overrides,
                             pure=False)
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            client.cancel(futures)


def in_file_order(paths: Sequence[str], results: Iterable[FileResult],
                  progress: Optional[Callable[[], None]] = None) -> List[FileResult]:
    """Collect the results (any order) in the order of the files."""
    by_path: Dict[str, List[FileResult]] = {}
    for result in results:
        by_path.setdefault(result.path, []).append(result)
        if progress is not None:
            progress()
    return [by_path[path].pop(0) for path in paths]


def _worst(rows: List[Dict[str, Any]], name: str) -> Optional[float]:
    errors = [row[f'{name}_relative_error'] for row in rows
              if row.get(f'{name}_relative_error') is not None
              and math.isfinite(row[f'{name}_relative_error'])]
    return max(errors, key=abs) if errors else None


def fleet_row(result: FileResult) -> Dict[str, Any]:
    """Return a file's row of the fleet report (JSON-ready)."""
    row: Dict[str, Any] = dict.fromkeys(FLEET_FIELDS)
    row.update(file=result.path, status=result.status, problem=result.problem)
    if result.analysis is None:
        return row
    recording = result.analysis.recording
    rows = result.analysis.rows
    row.update(recording.geometry.as_dict())
    row['drive'] = drive_values(recording.drive).get('drive')
    row.update(duration=recording.time_span, samples=recording.sample_count,
               segments=len(rows), stroke_pairs=sum(r['stroke_pairs'] for r in rows),
               worst_time_ratio_error=_worst(rows, 'time_ratio'),
               worst_speed_ratio_error=_worst(rows, 'speed_ratio'),
               lost_messages=sum(loss.messages or 0 for loss in recording.losses),
               losses=len(recording.losses))
    return finite_or_none(row)


def fleet_document(results: Sequence[FileResult]) -> Dict[str, Any]:
    """Return the fleet report as JSON: a row per file, and how many ended how."""
    rows = [fleet_row(result) for result in results]
    return {'units': 'SI (m, s, rad); errors are relative (measured / theory - 1)',
            'files': len(rows),
            'status': {status: sum(row['status'] == status for row in rows)
                       for status in (COMPLETE, INCOMPLETE, REFUSED, FAILED)},
            'recordings': rows}


def format_fleet_table(document: Dict[str, Any]) -> str:
    """Return the fleet report a person reads: one line per recording."""
    lines = [f'{"recording":<32} {"status":<10} {"r [mm]":>7} {"drive":<6} {"length [s]":>10} '
             f'{"segments":>8} {"pairs":>7} {"worst TR err":>12} {"worst SR err":>12} '
             f'{"lost":>6}']

    def shown(value, spec):
        return '-' if value is None else format(value, spec)
    for row in document['recordings']:
        name = os.path.basename(row['file'])
        radius = None if row['crank_radius'] is None else row['crank_radius'] * 1e3
        lines.append(
            f'{name[-32:]:<32} {row["status"]:<10} {shown(radius, "7.2f"):>7} '
            f'{shown(row["drive"], "s"):<6} {shown(row["duration"], "10.1f"):>10} '
            f'{shown(row["segments"], "d"):>8} {shown(row["stroke_pairs"], "d"):>7} '
            f'{shown(row["worst_time_ratio_error"], "+.2e"):>12} '
            f'{shown(row["worst_speed_ratio_error"], "+.2e"):>12} '
            f'{shown(row["lost_messages"], "d"):>6}')
    counts = ', '.join(f'{count} {status}' for status, count in document['status'].items()
                       if count)
    lines.append(f'{document["files"]} recordings: {counts}')
    return '\n'.join(lines)


def _write_fleet_csv(document: Dict[str, Any], path: str) -> None:
    with open(path, 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=list(FLEET_FIELDS))
        writer.writeheader()
        for row in document['recordings']:
            writer.writerow({k: ('' if v is None else v) for k, v in row.items()})


def write_fleet_report(results: Sequence[FileResult], document: Dict[str, Any],
                       folder: str) -> List[str]:
    """
    Write each analysed file's results and the fleet report into folder, all or nothing.

    folder/<file stem>/results.json and results.csv per file; folder/fleet.json, fleet.csv
    and the figure of TR error against offset over all recordings. Returns the paths.
    """
    from qrm_ros.analysis.fleet_figure import time_ratio_error_figure
    written: List[str] = []
    with staged_outputs() as stage:
        for name, result in zip(output_names([r.path for r in results]), results):
            if result.analysis is None:
                continue
            os.makedirs(os.path.join(folder, name), exist_ok=True)
            for writer, file_name in ((write_json_to, 'results.json'),
                                      (write_csv_to, 'results.csv')):
                path = os.path.join(folder, name, file_name)
                writer(result.analysis, stage(path))
                written.append(path)
        path = os.path.join(folder, 'fleet.json')
        with open(stage(path), 'w') as handle:
            json.dump(document, handle, indent=2, allow_nan=False)
            handle.write('\n')
        path_csv = os.path.join(folder, 'fleet.csv')
        _write_fleet_csv(document, stage(path_csv))
        figure_path = os.path.join(folder, FLEET_FIGURE)
        time_ratio_error_figure(results, stage(figure_path))
        written += [path, path_csv, figure_path]
    return written
