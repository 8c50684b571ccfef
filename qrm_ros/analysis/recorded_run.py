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
A recorded run as the analysis reads it: the geometry and the joint states as arrays.

``read_recording`` reads a run file (no ROS needed: the mcap reader and rosbags' CDR
deserializer), takes the geometry from its metadata (or from overrides), the masses, loads
and drive from the recorded parameters (qrm_ros.analysis.recorded_drive), and the joint
states as Samples. Nothing is lost in silence: a damaged chunk, an undecodable or malformed
message, a non-finite value or a truncated file is listed as Lost (how many messages, which
log-time span).
"""

import math
import os
import sys
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Sequence, TextIO, Tuple

import numpy as np

from qrm_ros.analysis.joint_state_decoding import (decode_in_parallel, decode_part, DecodedPart,
                                                   jazzy_typestore, JOINT_STATES_TOPIC,
                                                   MessageCounter)
from qrm_ros.analysis.recorded_drive import Drive, drive_changes, drive_from_metadata, DriveSpan
from qrm_ros.core import kinematics as kin
from qrm_ros.core.names import GEOMETRY_METADATA, JOINT_STATE_TYPE, PARAMETERS_METADATA
from qrm_ros.core.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.bag_reader import open_run, Run, RunFileError

GEOMETRY_FIELDS = kin.Geometry.field_names()
# Shortest steady run worth measuring (a stroke pair needs several samples anyway).
MIN_SEGMENT_SAMPLES = 3
PROGRESS_MIN_MESSAGES = 20000
# Very long runs are decoded in parallel worker processes, one per core (up to MAX_WORKERS).
# A worker costs about 0.7 s of CPU to start (its imports); with the block decoding, one
# process reads 360 000 joint states in 1.9 s where two workers took 8.5 s (medians,
# bench_analysis on 2 cores), so only far longer runs are split. Not measured above 1 h.
PARALLEL_MIN_MESSAGES = 2_000_000
MAX_WORKERS = 8
# The loss stages: not read from the file at all, read but not usable as a sample, or used
# as a sample without its efforts (the motion kept).
IN_FILE, IN_MESSAGE, IN_EFFORTS = 'file', 'message', 'efforts'


class AnalysisError(Exception):
    """Input that cannot be analysed; the message is the one line the user sees."""


class Samples(NamedTuple):
    """
    The recorded joint states as arrays (s, rad, rad/s, m, m/s, N m, N), in recording order.

    input_torque and offset_force are the first and last joint efforts; NaN where a message
    had no efforts, None when none had (recordings made before the node published them).
    """

    time: np.ndarray
    input_angle: np.ndarray
    input_speed: np.ndarray
    flywheel_angle: np.ndarray
    flywheel_speed: np.ndarray
    ram_position: np.ndarray
    ram_velocity: np.ndarray
    offset: np.ndarray
    offset_rate: np.ndarray
    input_torque: Optional[np.ndarray] = None
    offset_force: Optional[np.ndarray] = None
    # The crank radius joint (m, m/s); None in recordings made before the node published it
    # (their crank radius is the geometry's, from the metadata).
    crank_radius: Optional[np.ndarray] = None
    crank_radius_rate: Optional[np.ndarray] = None


class Lost(NamedTuple):
    """Joint-state messages left out of the analysis, and why (times: s of log time)."""

    stage: str  # IN_FILE: never read; IN_MESSAGE: read but not usable; IN_EFFORTS: see above
    reason: str
    messages: Optional[int]  # None: unknown
    start_time: Optional[float]  # from the recording's first message; None: unknown
    end_time: Optional[float]


class Recording(NamedTuple):
    path: str
    geometry: kin.Geometry
    samples: Samples
    problem: Optional[str]  # what is wrong with the file as a whole, if anything
    losses: Tuple[Lost, ...] = ()
    messages_in_file: Optional[int] = None  # the file's own count; None: unknown
    messages_read: Optional[int] = None
    repeated_stamps: int = 0  # exact repeats of the previous message, counted once
    drive: Optional[Drive] = None  # None: no theory of the efforts (drive_problem says why)
    drive_problem: Optional[str] = None
    # The masses, loads or drive changed mid-run (/parameter_events): what held from when.
    drive_changes: Tuple['DriveSpan', ...] = ()
    time_origin_ns: int = 0  # the stamp of samples.time 0

    def drive_spans(self) -> Tuple['DriveSpan', ...]:
        """Return what drove the machine, from the start (-inf) through each change."""
        return (DriveSpan(-math.inf, self.drive, self.drive_problem),) + self.drive_changes

    @property
    def complete(self) -> bool:
        return self.problem is None and not self.losses


def _progress(stream: TextIO, total: int) -> Callable[[int], None]:
    """Return a callback drawing a progress bar of `total` messages on stream."""
    width = 40

    def update(done):
        filled = width * done // total
        stream.write(f'\rreading joint states [{"#" * filled}{"." * (width - filled)}] '
                     f'{100 * done // total:3d}%')
        if done >= total:
            stream.write('\n')
        stream.flush()
    update.total = total  # type: ignore[attr-defined]
    return update


def read_recording(path: str, geometry_overrides: Optional[Dict[str, Optional[float]]] = None,
                   progress_stream: TextIO = sys.stderr) -> Recording:
    """Read a run file's geometry and joint states; AnalysisError says what is missing."""
    try:
        run = open_run(path)
    except RunFileError as error:
        raise AnalysisError(str(error)) from None
    try:
        _check_joint_states(run, path)
        geometry = _geometry(run.metadata.get(GEOMETRY_METADATA, {}),
                             geometry_overrides or {}, path)
        stored = run.metadata.get(PARAMETERS_METADATA)
        drive, drive_problem = drive_from_metadata(stored, geometry)
    except AnalysisError as error:
        if run.truncated:  # say why the topic or the metadata may be missing
            raise AnalysisError(f'{error}; note: {run.problem}') from None
        raise
    total = run.message_count(JOINT_STATES_TOPIC)
    progress = None
    if progress_stream.isatty() and total >= PROGRESS_MIN_MESSAGES:
        progress = _progress(progress_stream, total)  # a bar only for a person, on long files
    workers = min(usable_cores(), MAX_WORKERS) if total >= PARALLEL_MIN_MESSAGES else 1
    file_parts = run.parts(workers)
    if len(file_parts) == 1:
        parts = [decode_part(path, file_parts[0], MessageCounter(), progress, run)]
    else:
        parts = decode_in_parallel(path, file_parts, progress)
    recording = _combine(path, run, geometry, parts)
    return recording._replace(drive=drive, drive_problem=drive_problem,
                              drive_changes=drive_changes(run, stored, geometry,
                                                          recording.time_origin_ns))


def usable_cores() -> int:
    """Cores this process may run on (taskset, cgroups), not the machine's count."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _check_joint_states(run: Run, path: str) -> None:
    """Refuse a joint-state channel this decoder would misread (encoding, definition)."""
    topics = run.topics()
    if topics.get(JOINT_STATES_TOPIC) != JOINT_STATE_TYPE:
        present = ', '.join(f'{t} ({s})' for t, s in sorted(topics.items())) or 'none'
        raise AnalysisError(f'{path} has no {JOINT_STATES_TOPIC} topic of type '
                            f'{JOINT_STATE_TYPE} (topics present: {present})')
    channel = run.channel(JOINT_STATES_TOPIC)
    if channel.message_encoding != 'cdr':
        raise AnalysisError(f'{path}: {JOINT_STATES_TOPIC} is encoded as '
                            f'{channel.message_encoding!r}, not CDR')
    schema = run.schema(channel)
    if schema is None or not schema.data:
        return  # no definition recorded: trust the type name, as rosbag2 does
    from rosbags.typesys import get_types_from_idl, get_types_from_msg
    parsers: Dict[str, Callable[[str, str], Any]] = {
        'ros2msg': get_types_from_msg,
        'ros2idl': lambda text, _: get_types_from_idl(text)}  # an IDL names its own types
    parse = parsers.get(schema.encoding)
    if parse is None:
        raise AnalysisError(f'{path}: the definition of {JOINT_STATE_TYPE} is in an unknown '
                            f'encoding {schema.encoding!r} (expected ros2msg or ros2idl)')
    try:
        recorded = parse(schema.data.decode('utf-8'), JOINT_STATE_TYPE)
    except Exception as error:  # rosbags' parser raises several types on malformed text
        raise AnalysisError(f'{path}: the recorded definition of {JOINT_STATE_TYPE} is '
                            f'unreadable ({type(error).__name__})') from None
    known = jazzy_typestore().fielddefs
    for name, definition in recorded.items():
        if name in known and tuple(definition[1]) != tuple(known[name][1]):
            raise AnalysisError(f'{path}: the recorded definition of {name} differs from ROS 2 '
                                'Jazzy\'s; this analysis decodes the standard one only')


def _seconds(log_time: Optional[int], start: Optional[int]) -> Optional[float]:
    if log_time is None or start is None:
        return None
    return (log_time - start) / NANOSECONDS_PER_SECOND


def _combine(path: str, run: Run, geometry: kin.Geometry, parts: List[DecodedPart]) -> Recording:
    """Join the parts in file order; exclude what is unusable and list it."""
    start = run.start_time
    losses: List[Lost] = []
    for part in parts:
        for loss in part.losses:
            losses.append(Lost(IN_FILE, loss.reason, loss.messages,
                               _seconds(loss.start_time, start), _seconds(loss.end_time, start)))
    read = sum(part.read for part in parts)
    in_file = run.message_count(JOINT_STATES_TOPIC) if run.counted else None
    if in_file is not None:
        # The statistics count every message written: the exact toll of the damage, whatever
        # the damaged chunks' own message indexes said.
        unread = in_file - read - sum(loss.messages or 0 for loss in losses)
        if unread or any(loss.messages is None for loss in losses):
            losses.append(Lost(IN_FILE, f'in all, {in_file - read} of the {in_file} messages '
                               'the file counts could not be read', unread, None, None))
    if not run.data_complete:
        last = max((int(part.log_times.max()) for part in parts if part.log_times.size),
                   default=None)
        losses.append(Lost(IN_FILE, 'messages after the last whole record (how many is '
                           'unknown)', None, _seconds(last, start), None))
    rejected: Dict[str, List[int]] = {}
    for part in parts:
        for reason, (count, first, last) in part.rejected.items():
            entry = rejected.setdefault(reason, [0, first, last])
            entry[:] = [entry[0] + count, min(entry[1], first), max(entry[2], last)]
    stamps = np.concatenate([part.stamps for part in parts])
    log_times = np.concatenate([part.log_times for part in parts])
    position = np.concatenate([part.positions for part in parts])
    velocity = np.concatenate([part.velocities for part in parts])
    effort = np.concatenate([part.efforts for part in parts])
    radius = np.concatenate([_column(part.crank_radius, part.stamps) for part in parts])
    radius_rate = np.concatenate([_column(part.crank_radius_rate, part.stamps)
                                  for part in parts])
    finite = np.isfinite(position).all(axis=1) & np.isfinite(velocity).all(axis=1)
    if not finite.all():
        bad = log_times[~finite]
        rejected['non-finite positions or velocities'] = [int(bad.size), int(bad.min()),
                                                          int(bad.max())]
    stamps, log_times = stamps[finite], log_times[finite]
    position, velocity, effort = position[finite], velocity[finite], effort[finite]
    radius, radius_rate = radius[finite], radius_rate[finite]
    # A recorded effort that is not finite is not a measurement: the sample keeps its motion,
    # its efforts count as not recorded (NaN), and how many is listed.
    recorded = ~np.isnan(effort).all(axis=1)
    unusable = recorded & ~np.isfinite(effort).all(axis=1)
    if unusable.any():
        effort[unusable] = np.nan
        bad = log_times[unusable]
        losses.append(Lost(IN_EFFORTS, 'non-finite efforts (the motion kept)', int(bad.size),
                           _seconds(int(bad.min()), start), _seconds(int(bad.max()), start)))
    # The same stamp as the previous message: an exact repeat counts once; a conflicting
    # one is excluded (which of the two is right cannot be told).
    repeat = np.zeros(stamps.size, dtype=bool)
    repeat[1:] = np.diff(stamps) == 0
    same = np.zeros_like(repeat)
    same[1:] = ((position[1:] == position[:-1]).all(axis=1)
                & (velocity[1:] == velocity[:-1]).all(axis=1)
                & ((effort[1:] == effort[:-1]) | (np.isnan(effort[1:]) & np.isnan(effort[:-1]))
                   ).all(axis=1))
    conflicting = repeat & ~same
    if conflicting.any():
        bad = log_times[conflicting]
        rejected['the stamp of the previous message with other values'] = [
            int(bad.size), int(bad.min()), int(bad.max())]
    for reason, (count, first, last) in sorted(rejected.items()):
        losses.append(Lost(IN_MESSAGE, reason, count, _seconds(first, start),
                           _seconds(last, start)))
    keep = ~repeat
    stamps, position, velocity = stamps[keep], position[keep], velocity[keep]
    effort = effort[keep]
    radius, radius_rate = radius[keep], radius_rate[keep]
    # The crank radius where every sample has it (a recording of this version's node).
    with_radius = bool(radius.size and np.isfinite(radius).all()
                       and np.isfinite(radius_rate).all())
    if stamps.size < MIN_SEGMENT_SAMPLES:
        raise AnalysisError(f'{path} holds {stamps.size} usable {JOINT_STATES_TOPIC} messages: '
                            'too few to find any stroke' + _loss_clause(losses, run))
    time = (stamps - stamps[0]) / NANOSECONDS_PER_SECOND
    with_efforts = not np.isnan(effort).all()
    samples = Samples(time, position[:, 0], velocity[:, 0], position[:, 1], velocity[:, 1],
                      position[:, 3], velocity[:, 3], position[:, 4], velocity[:, 4],
                      effort[:, 0] if with_efforts else None,
                      effort[:, -1] if with_efforts else None,
                      radius if with_radius else None, radius_rate if with_radius else None)
    return Recording(path, geometry, samples, run.problem if run.truncated else None,
                     tuple(losses), in_file, read, int((repeat & same).sum()),
                     time_origin_ns=int(stamps[0]))


def _column(values: Optional[np.ndarray], stamps: np.ndarray) -> np.ndarray:
    """Return a decoded part's crank radius column, NaN where it has none."""
    return np.full(stamps.shape, np.nan) if values is None else values


def _loss_clause(losses: Sequence[Lost], run: Run) -> str:
    reasons = [loss.reason for loss in losses[:3]]
    if run.truncated and run.problem:
        reasons.insert(0, run.problem)
    return f' ({"; ".join(reasons)})' if reasons else ''


def _geometry(stored: Dict[str, str], overrides: Dict[str, Optional[float]],
              path: str) -> kin.Geometry:
    values: Dict[str, float] = {}
    for name in GEOMETRY_FIELDS:
        override = overrides.get(name)
        if override is not None:
            values[name] = override
        elif name in stored:
            try:
                values[name] = float(stored[name])
            except ValueError:
                raise AnalysisError(
                    f'{path}: the {GEOMETRY_METADATA} metadata value of {name} is not a number '
                    f'({stored[name][:40]!r}): give it with --{name.replace("_", "-")}') from None
    missing = [name for name in GEOMETRY_FIELDS[:4] if name not in values]
    if missing:
        options = ' '.join('--' + name.replace('_', '-') for name in missing)
        raise AnalysisError(f'{path} has no {GEOMETRY_METADATA} metadata for '
                            f'{", ".join(missing)}: give them with {options}')
    try:
        return kin.Geometry(**values)
    except kin.KinematicsError as error:
        raise AnalysisError(f'{path}: bad geometry: {error}') from None
