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
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Sequence, TextIO, Tuple

import numpy as np

from qrm_ros.analysis.joint_state_decoding import (decode_in_parallel, decode_part, DecodedBlock,
                                                   DecodedPart, JOINT_STATES_TOPIC, MessageCounter)
from qrm_ros.analysis.recorded_drive import Drive, drive_changes, drive_from_metadata, DriveSpan
from qrm_ros.analysis.sample_consistency import foreign_geometry_problem
# The loss stages and Lost are read from here too (they were defined here first).
from qrm_ros.analysis.sample_checks import (CheckedBlock, IN_EFFORTS, IN_FILE,  # noqa: F401
                                            IN_MESSAGE, Lost, merge_counts, SampleChecks)
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import GEOMETRY_METADATA, JOINT_STATE_TYPE, PARAMETERS_METADATA
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.bag_reader import open_run, Run, RunFileError
from qrm_ros.recording.mcap_recover import recovered_losses
from qrm_ros.recording.typestore import jazzy_typestore

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


class RunExtent(NamedTuple):
    """The size of a run streamed through (its samples then hold only excerpts)."""

    samples: int  # samples used
    time_span: float  # s, from the earliest to the latest sample
    efforts_recorded: bool  # whether any sample carries efforts
    # Each segment's [start, end) sample indices in the whole run (its samples are excerpts).
    segment_spans: Tuple[Tuple[int, int], ...] = ()


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
    # Set when the run was streamed (qrm_ros.analysis.streamed_run): samples then hold only
    # what the figures draw, and this tells the whole run's size.
    extent: Optional[RunExtent] = None

    @property
    def sample_count(self) -> int:
        """Samples used from the whole run."""
        return self.extent.samples if self.extent else int(self.samples.time.size)

    @property
    def time_span(self) -> float:
        """Seconds from the earliest to the latest sample of the whole run."""
        if self.extent:
            return self.extent.time_span
        return float(np.ptp(self.samples.time)) if self.samples.time.size else 0.0

    @property
    def efforts_recorded(self) -> bool:
        """Whether any sample of the run carries efforts."""
        return self.extent.efforts_recorded if self.extent else (
            self.samples.input_torque is not None)

    def drive_spans(self) -> Tuple['DriveSpan', ...]:
        """Return what drove the machine, from the start (-inf) through each change."""
        return (DriveSpan(-math.inf, self.drive, self.drive_problem),) + self.drive_changes

    @property
    def complete(self) -> bool:
        return (self.problem is None and not self.losses
                and not any(span.unreadable for span in self.drive_changes))


def progress_bar(stream: TextIO, total: int) -> Callable[[int], None]:
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


class OpenedRun(NamedTuple):
    """A run file opened for analysis: what it holds beside its joint states."""

    run: Run
    geometry: kin.Geometry
    stored_parameters: Optional[Dict[str, str]]
    drive: Optional[Drive]
    drive_problem: Optional[str]


def open_for_analysis(path: str, geometry_overrides: Optional[Dict[str, Optional[float]]] = None
                      ) -> OpenedRun:
    """Open a run file, check its joint-state channel, read its geometry and drive."""
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
    return OpenedRun(run, geometry, stored, drive, drive_problem)


def read_recording(path: str, geometry_overrides: Optional[Dict[str, Optional[float]]] = None,
                   progress_stream: Optional[TextIO] = None) -> Recording:
    """
    Read a run file's geometry and joint states; AnalysisError says what is missing.

    progress_stream: where a progress bar goes when it is a terminal (None: no bar).
    """
    run, geometry, stored, drive, drive_problem = open_for_analysis(path, geometry_overrides)
    total = run.message_count(JOINT_STATES_TOPIC)
    progress = None
    if progress_stream is not None and progress_stream.isatty() and (
            total >= PROGRESS_MIN_MESSAGES):
        progress = progress_bar(progress_stream, total)  # a bar for a person, on long files
    workers = min(usable_cores(), MAX_WORKERS) if total >= PARALLEL_MIN_MESSAGES else 1
    file_parts = run.parts(workers)
    if len(file_parts) == 1:
        parts = [decode_part(path, file_parts[0], MessageCounter(), progress, run)]
    else:
        parts = decode_in_parallel(path, file_parts, progress)
    recording = with_recovery_losses(_combine(path, run, geometry, parts), run.metadata)
    return recording._replace(drive=drive, drive_problem=drive_problem,
                              drive_changes=drive_changes(run, stored, geometry,
                                                          recording.time_origin_ns))


def with_recovery_losses(recording: Recording, metadata: Dict[str, Dict[str, str]]) -> Recording:
    """Say again what a recovery (mcap_recorder --recover) lost before this file was made."""
    losses = recovered_losses(metadata)
    if not losses:
        return recording
    said = 'recovered with losses by mcap_recorder --recover: ' + '; '.join(losses)
    problem = f'{recording.problem}; {said}' if recording.problem else said
    return recording._replace(problem=problem)


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


def _combine(path: str, run: Run, geometry: kin.Geometry, parts: List[DecodedPart]) -> Recording:
    """Join the parts in file order; exclude what is unusable and list it."""
    checks = SampleChecks(geometry)
    checked: List[CheckedBlock] = []
    for part in parts:
        checks.file_losses += part.losses
        for reason, (count, first, last) in part.rejected.items():
            merge_counts(checks.rejected, reason, count, first, last)
        checked.append(checks.check(DecodedBlock(part.stamps, part.log_times, part.positions,
                                                 part.velocities, part.efforts, part.read,
                                                 part.crank_radius, part.crank_radius_rate)))
    losses = checks.losses(run)
    foreign = foreign_geometry_problem(path, geometry, checks.inconsistent, checks.used)
    if foreign:
        raise AnalysisError(foreign)
    if checks.used < MIN_SEGMENT_SAMPLES:
        raise too_few_samples(path, checks.used, losses, run)
    stamps = np.concatenate([block.stamps for block in checked])
    samples = samples_of(CheckedBlock(stamps, *(np.concatenate([getattr(block, name)
                                                                for block in checked])
                                                for name in CheckedBlock._fields[1:])),
                         int(stamps[0]), None)
    return Recording(path, geometry, samples, run.problem if run.truncated else None,
                     tuple(losses), checks.messages_in_file(run), checks.read, checks.repeated,
                     time_origin_ns=int(stamps[0]))


def samples_of(block: CheckedBlock, origin_ns: int, with_efforts: Optional[bool]) -> Samples:
    """
    Return checked samples as Samples, time from origin_ns (the run's first sample's stamp).

    with_efforts: whether the run recorded efforts (None: whether this block holds any).
    """
    time = (block.stamps - origin_ns) / NANOSECONDS_PER_SECOND
    position, velocity, effort = block.positions, block.velocities, block.efforts
    if with_efforts is None:
        with_efforts = not np.isnan(effort).all()
    radius, radius_rate = block.crank_radius, block.crank_radius_rate
    # The crank radius where every sample has it (a recording of a node that publishes it).
    with_radius = (radius is not None and radius_rate is not None and bool(radius.size)
                   and bool(np.isfinite(radius).all() and np.isfinite(radius_rate).all()))
    return Samples(time, position[:, 0], velocity[:, 0], position[:, 1], velocity[:, 1],
                   position[:, 3], velocity[:, 3], position[:, 4], velocity[:, 4],
                   effort[:, 0] if with_efforts else None,
                   effort[:, -1] if with_efforts else None,
                   radius if with_radius else None, radius_rate if with_radius else None)


def too_few_samples(path: str, used: int, losses: Sequence[Lost], run: Run) -> AnalysisError:
    """Return the refusal of a run with too few usable samples to find a stroke."""
    return AnalysisError(f'{path} holds {used} usable {JOINT_STATES_TOPIC} messages: '
                         'too few to find any stroke' + _loss_clause(losses, run))


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
