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
Offline analysis of a recorded run: measured time and speed ratios per offset, vs theory.

``qrm_analyze RUN.mcap`` reads the joint states of a recording (no ROS needed: the mcap
reader and rosbags' CDR deserializer), splits the run into segments of steady offset and
input speed, measures every stroke pair in each (qrm_ros.strokes: reversals and peaks located
between samples), and compares the means with the core's closed form for the geometry stored
in the file. Output: a table, CSV, JSON and the paper's figures (``--plot DIR``).

Exit status: 0 analysed; 2 the input could not be analysed (one-line reason on stderr);
3 analysed, but the file was truncated (what was lost is said on stderr).
"""

import argparse
import concurrent.futures
import contextlib
import csv
import json
import math
import multiprocessing
import os
import sys
from typing import NamedTuple

import numpy as np

from qrm_ros import kinematics as kin
from qrm_ros.bag_reader import open_run, RunFileError
from qrm_ros.design_table import add_geometry_arguments
from qrm_ros import names
from qrm_ros.names import absolute_topic, GEOMETRY_METADATA, JOINT_NAMES, JOINT_STATE_TYPE
from qrm_ros.strokes import find_stroke_pairs

JOINT_STATES_TOPIC = absolute_topic(names.JOINT_STATES_TOPIC)
GEOMETRY_FIELDS = kin.Geometry.field_names()
# Samples whose offset and input speed differ by less than this (relative) are one setting.
STEADY_TOLERANCE = 1e-12
# Shortest steady run worth measuring (a stroke pair needs several samples anyway).
MIN_SEGMENT_SAMPLES = 3
EXIT_BAD_INPUT, EXIT_TRUNCATED = 2, 3
# Below this, the between-sample interpolation can miss sharp speed peaks (large offsets).
MIN_SAMPLES_PER_REVOLUTION = 60
PROGRESS_MIN_MESSAGES = 20000
PROGRESS_STEP = 5000
# Long runs are decoded in parallel worker processes, one per core (up to MAX_WORKERS).
PARALLEL_MIN_MESSAGES = 100_000
MAX_WORKERS = 8


class AnalysisError(Exception):
    """Input that cannot be analysed; the message is the one line the user sees."""


class Samples(NamedTuple):
    """The recorded joint states as arrays (s, rad, rad/s, m, m/s)."""

    time: np.ndarray
    input_angle: np.ndarray
    input_speed: np.ndarray
    flywheel_angle: np.ndarray
    flywheel_speed: np.ndarray
    ram_position: np.ndarray
    ram_velocity: np.ndarray
    offset: np.ndarray
    offset_rate: np.ndarray


class Recording(NamedTuple):
    path: str
    geometry: kin.Geometry
    samples: Samples
    problem: object  # str if the file was truncated, else None


def _progress(stream, total):
    """Return a callback drawing a progress bar of `total` messages on stream."""
    width = 40

    def update(done):
        filled = width * done // total
        stream.write(f'\rreading joint states [{"#" * filled}{"." * (width - filled)}] '
                     f'{100 * done // total:3d}%')
        if done >= total:
            stream.write('\n')
        stream.flush()
    update.total = total
    return update


def _typestore():
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


def read_recording(path, geometry_overrides=None, progress_stream=sys.stderr):
    """Read a run file's geometry and joint states; AnalysisError says what is missing."""
    try:
        run = open_run(path)
    except RunFileError as error:
        raise AnalysisError(str(error)) from None
    geometry = _geometry(run.metadata.get(GEOMETRY_METADATA, {}), geometry_overrides or {},
                         path)
    topics = run.topics()
    if topics.get(JOINT_STATES_TOPIC) != JOINT_STATE_TYPE:
        present = ', '.join(f'{t} ({s})' for t, s in sorted(topics.items())) or 'none'
        raise AnalysisError(f'{path} has no {JOINT_STATES_TOPIC} topic of type '
                            f'{JOINT_STATE_TYPE} (topics present: {present})')
    total = run.message_count(JOINT_STATES_TOPIC)
    progress = None
    if progress_stream.isatty() and total >= PROGRESS_MIN_MESSAGES:
        progress = _progress(progress_stream, total)  # a bar only for a person, on long files
    workers = min(os.cpu_count() or 1, MAX_WORKERS) if total >= PARALLEL_MIN_MESSAGES else 1
    spans = run.time_spans(workers)
    if len(spans) == 1:
        counter = _Counter()
        parts = [_decode_span(path, None, None, counter, progress)]
    else:
        parts = _decode_in_parallel(path, spans, progress)
    names = parts[0][0]
    for part in parts[1:]:
        if part[0] is not None and part[0] != names:
            raise AnalysisError(f'{path}: the joints of {JOINT_STATES_TOPIC} change during '
                                f'the run ({names} then {part[0]})')
    stamp = np.concatenate([part[1] for part in parts])
    if stamp.size < 3:
        raise AnalysisError(f'{path} holds {stamp.size} {JOINT_STATES_TOPIC} messages: too few '
                            'to find any stroke')
    joint_order = _joint_order(names, path)
    order = np.argsort(stamp, kind='stable')  # the spans and the file order are not sorted
    stamp = stamp[order]
    keep = np.concatenate([[True], np.diff(stamp) > 0])  # a stamp published twice counts once
    time = (stamp[keep] - stamp[0]) * 1e-9
    position = np.concatenate([part[2] for part in parts])[order][keep][:, joint_order]
    velocity = np.concatenate([part[3] for part in parts])[order][keep][:, joint_order]
    samples = Samples(time, position[:, 0], velocity[:, 0], position[:, 1], velocity[:, 1],
                      position[:, 3], velocity[:, 3], position[:, 4], velocity[:, 4])
    return Recording(path, geometry, samples, run.problem if run.truncated else None)


class _Counter:
    """Messages decoded so far (a shared multiprocessing.Value in worker processes)."""

    def __init__(self):
        self.value = 0

    def get_lock(self):
        return contextlib.nullcontext()


_worker_counter = None


def _start_worker(counter):
    global _worker_counter
    _worker_counter = counter


def _decode_span(path, starting_at, ending_before, counter=None, progress=None):
    """
    Decode the joint states of a log-time span: (names, stamps, positions, velocities).

    The hot loop of a long file: one decode and three appends per message.
    """
    counter = counter or _worker_counter
    deserialize = _typestore().deserialize_cdr
    stamps, positions, velocities = [], [], []
    names = None
    run = open_run(path)
    messages = run.messages([JOINT_STATES_TOPIC], log_time_order=False,  # sorted later
                            starting_at=starting_at, ending_before=ending_before)
    for count, (_, _, _, _, data) in enumerate(messages, 1):
        message = deserialize(data, JOINT_STATE_TYPE)
        if message.name != names:
            if names is not None:
                raise AnalysisError(f'{path}: the joints of {JOINT_STATES_TOPIC} change during '
                                    f'the run ({names} then {message.name})')
            names = message.name
        stamp = message.header.stamp
        stamps.append(stamp.sec * 1_000_000_000 + stamp.nanosec)
        positions.append(message.position)
        velocities.append(message.velocity)
        if count % PROGRESS_STEP == 0:
            with counter.get_lock():
                counter.value += PROGRESS_STEP
            if progress is not None:
                progress(counter.value)
    if progress is not None:
        progress(run.message_count(JOINT_STATES_TOPIC))
    return (names, np.asarray(stamps, dtype=np.int64),
            np.asarray(positions).reshape(-1, len(names or JOINT_NAMES)),
            np.asarray(velocities).reshape(-1, len(names or JOINT_NAMES)))


def _decode_in_parallel(path, spans, progress):
    """Decode spans in worker processes (long runs: decoding is per-message Python work)."""
    context = multiprocessing.get_context('spawn')  # no fork of a process that may hold DDS
    counter = context.Value('q', 0)
    with concurrent.futures.ProcessPoolExecutor(len(spans), mp_context=context,
                                                initializer=_start_worker,
                                                initargs=(counter,)) as pool:
        futures = [pool.submit(_decode_span, path, start, end) for start, end in spans]
        while not all(future.done() for future in futures):
            concurrent.futures.wait(futures, timeout=0.2)
            if progress is not None:
                progress(min(counter.value, progress.total - 1))
        parts = [future.result() for future in futures]
    if progress is not None:
        progress(progress.total)
    return parts


def _joint_order(names, path):
    try:
        return np.array([list(names).index(joint) for joint in JOINT_NAMES])
    except ValueError:
        missing = [joint for joint in JOINT_NAMES if joint not in names]
        raise AnalysisError(f'{path}: joint_states lacks the joints {", ".join(missing)}') \
            from None


def _geometry(stored, overrides, path):
    values = {}
    for name in GEOMETRY_FIELDS:
        if overrides.get(name) is not None:
            values[name] = overrides[name]
        elif name in stored:
            values[name] = float(stored[name])
    missing = [name for name in GEOMETRY_FIELDS[:4] if name not in values]
    if missing:
        options = ' '.join('--' + name.replace('_', '-') for name in missing)
        raise AnalysisError(f'{path} has no {GEOMETRY_METADATA} metadata for '
                            f'{", ".join(missing)}: give them with {options}')
    try:
        return kin.Geometry(**values)
    except kin.KinematicsError as error:
        raise AnalysisError(f'{path}: bad geometry: {error}') from None


class Segment(NamedTuple):
    start: int  # sample indices, end exclusive
    end: int
    offset: float
    input_speed: float


def split_segments(samples):
    """
    Split into spans of steady offset and input speed; return (segments, transitions).

    A segment is a maximal run of samples that share one offset and one input speed with
    the offset actuator at rest (a ramp changes the speed at every sample, so its samples
    never form a run); what lies between segments is a transition, excluded from the
    measurement and reported.
    """
    offset, speed = samples.offset, samples.input_speed
    scale = max(1.0, float(np.max(np.abs(speed))))
    changed = ((np.abs(np.diff(offset)) > STEADY_TOLERANCE)
               | (np.abs(np.diff(speed)) > STEADY_TOLERANCE * scale))
    steady = samples.offset_rate == 0.0
    starts = np.flatnonzero(np.concatenate([[True], changed | (steady[1:] != steady[:-1])]))
    ends = np.append(starts[1:], offset.size)
    segments = [Segment(int(a), int(b), float(offset[a]), float(speed[a]))
                for a, b in zip(starts, ends) if steady[a] and b - a >= MIN_SEGMENT_SAMPLES]
    transitions = []
    for before, after in zip(segments, segments[1:]):
        changes = []
        if after.offset != before.offset:
            changes.append(f'offset {before.offset * 1e3:g} -> {after.offset * 1e3:g} mm')
        if after.input_speed != before.input_speed:
            changes.append(f'input speed {before.input_speed:g} -> {after.input_speed:g} rad/s')
        transitions.append({
            'start_time': float(samples.time[before.end - 1]),
            'end_time': float(samples.time[after.start]),
            'offset_from': before.offset, 'offset_to': after.offset,
            'input_speed_from': before.input_speed, 'input_speed_to': after.input_speed,
            'change': ', '.join(changes) or 'interruption'})
    return segments, transitions


def _relative_error(measured, theory):
    if not (math.isfinite(measured) and math.isfinite(theory)) or theory == 0.0:
        return None
    return measured / theory - 1.0


def _mean_and_spread(values):
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return None, None
    spread = float(np.std(values, ddof=1)) if values.size > 1 else 0.0
    return float(np.mean(values)), spread


def measure_segment(samples, segment, geometry):
    """Measured and theoretical figures of one steady segment, as a JSON-ready dict."""
    span = slice(segment.start, segment.end)
    pairs = find_stroke_pairs(samples.time[span], samples.ram_position[span],
                              samples.ram_velocity[span])
    row = {
        'offset': segment.offset,
        'offset_over_pivot_distance': segment.offset / geometry.pivot_distance,
        'input_speed': segment.input_speed,
        'start_time': float(samples.time[segment.start]),
        'end_time': float(samples.time[segment.end - 1]),
        'stroke_pairs': int(len(pairs.time_ratio)),
        'samples_per_revolution': None,
    }
    if segment.input_speed != 0.0:
        step = float(np.median(np.diff(samples.time[span])))
        row['samples_per_revolution'] = 2 * math.pi / (abs(segment.input_speed) * step)
    measured = {
        'time_ratio': pairs.time_ratio, 'speed_ratio': pairs.speed_ratio,
        'peak_speed_ratio': pairs.peak_speed_ratio, 'cutting_time': pairs.cutting_time,
        'return_time': pairs.return_time, 'peak_cutting_speed': pairs.peak_cutting_speed,
        'peak_return_speed': pairs.peak_return_speed}
    theory = {name: None for name in measured}
    if segment.input_speed != 0.0 and abs(segment.offset) < geometry.coupling_radius:
        theory.update(kin.steady_theory(geometry, segment.offset, segment.input_speed)._asdict())
    for name, values in measured.items():
        mean, spread = _mean_and_spread(values)
        row[f'{name}_measured'] = mean
        row[f'{name}_measured_std'] = spread
        row[f'{name}_theory'] = theory[name]
        row[f'{name}_relative_error'] = (None if mean is None or theory[name] is None
                                         else _relative_error(mean, theory[name]))
    return row


class Analysis(NamedTuple):
    recording: Recording
    segments: list
    rows: list
    transitions: list


def analyse(recording):
    segments, transitions = split_segments(recording.samples)
    rows = [measure_segment(recording.samples, s, recording.geometry) for s in segments]
    return Analysis(recording, segments, rows, transitions)


def _fmt(value, spec):
    width = spec.lstrip('+-').split('.')[0]
    return format('-', '>' + width) if value is None else format(value, spec)


def format_table(analysis):
    recording = analysis.recording
    geometry = recording.geometry
    samples = recording.samples
    lines = [
        f'{recording.path}: {samples.time.size} joint-state samples over '
        f'{samples.time[-1]:.3f} s',
        f'geometry: r1 = {geometry.coupling_radius * 1e3:g} mm, r = '
        f'{geometry.crank_radius * 1e3:g} mm, h = {geometry.pivot_distance * 1e3:g} mm, '
        f'H = {geometry.ram_height * 1e3:g} mm, crank phase = {geometry.crank_phase:g} rad',
        '',
        ' offset  offset/h    input  pairs |      TR measured  TR theory  rel.err |'
        '      SR measured  SR theory  rel.err | peak SR measured  theory   rel.err',
        '   [mm]       [-]  [rad/s]    [-] |                                      |'
        '                                      |',
    ]
    for row in analysis.rows:
        parts = [f'{row["offset"] * 1e3:7.2f} {row["offset_over_pivot_distance"]:+9.5f} '
                 f'{row["input_speed"]:8.4f} {row["stroke_pairs"]:6d} |']
        for name in ('time_ratio', 'speed_ratio', 'peak_speed_ratio'):
            mean, spread = row[f'{name}_measured'], row[f'{name}_measured_std']
            measured = '-' if mean is None else f'{mean:8.5f} ± {spread:.1e}'
            parts.append(f' {measured:>16} {_fmt(row[name + "_theory"], "10.5f")} '
                         f'{_fmt(row[name + "_relative_error"], "+8.1e")} |')
        lines.append(''.join(parts)[:-2])
    if not analysis.rows:
        lines.append('  (no segment of steady offset and input speed)')
    for row in analysis.rows:
        per_turn = row['samples_per_revolution']
        if per_turn is not None and per_turn < MIN_SAMPLES_PER_REVOLUTION:
            lines.append(
                f'warning: offset {row["offset"] * 1e3:g} mm at {row["input_speed"]:g} rad/s '
                f'has only {per_turn:.0f} samples per input revolution (fewer than '
                f'{MIN_SAMPLES_PER_REVOLUTION}): reversals and peaks between samples are '
                'uncertain; record at a higher publish_rate')
    for t in analysis.transitions:
        lines.append(f'transition {t["start_time"]:.3f}-{t["end_time"]:.3f} s excluded: '
                     f'{t["change"]}')
    return '\n'.join(lines)


def to_document(analysis):
    recording = analysis.recording
    return {
        'file': recording.path,
        'truncated': recording.problem,
        'units': 'SI (m, s, rad, rad/s, m/s); ratios dimensionless',
        'geometry': recording.geometry.as_dict(),
        'segments': analysis.rows,
        'transitions': analysis.transitions,
    }


def write_csv(analysis, path):
    fields = list(analysis.rows[0]) if analysis.rows else ['offset']
    with open(path, 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for row in analysis.rows:
            writer.writerow({k: ('' if v is None else v) for k, v in row.items()})


def write_json(analysis, path):
    with open(path, 'w') as handle:
        json.dump(to_document(analysis), handle, indent=2, allow_nan=False)
        handle.write('\n')


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog='qrm_analyze',
        description='Measure time ratio and speed ratio per offset in a recorded run and '
                    'compare them with the closed form.')
    parser.add_argument('run', help='recorded run (.mcap) from mcap_recorder')
    parser.add_argument('--csv', metavar='FILE', help='write the per-segment table as CSV')
    parser.add_argument('--json', metavar='FILE', help='write the results as JSON')
    parser.add_argument('--plot', metavar='DIR', help='write the figures (PNG) into DIR')
    geometry_group = parser.add_argument_group(
        'geometry', 'override (or supply, for files without it) the stored geometry')
    add_geometry_arguments(geometry_group, defaults=False)
    args = parser.parse_args(argv)
    overrides = {name: getattr(args, name) for name in GEOMETRY_FIELDS}
    try:
        recording = read_recording(args.run, overrides)
        analysis = analyse(recording)
        print(format_table(analysis))
        if args.csv:
            write_csv(analysis, args.csv)
        if args.json:
            write_json(analysis, args.json)
        if args.plot:
            from qrm_ros.figures import write_figures
            for path in write_figures(analysis, args.plot):
                print(f'figure: {path}')
    except AnalysisError as error:
        print(f'qrm_analyze: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as error:
        print(f'qrm_analyze: error: {error.filename or ""}: {error.strerror}', file=sys.stderr)
        return EXIT_BAD_INPUT
    if recording.problem:
        print(f'qrm_analyze: warning: {args.run} is truncated: {recording.problem}; the '
              'figures above cover what was whole', file=sys.stderr)
        return EXIT_TRUNCATED
    return 0


if __name__ == '__main__':
    sys.exit(main())
