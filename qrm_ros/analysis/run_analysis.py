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
input speed without gaps, measures every stroke pair in each (qrm_ros.core.strokes: reversals and
peaks located between samples), and compares the means with the core's closed form for the
geometry stored in the file. Output: a table, CSV, JSON and the paper's figures (``--plot``).

Nothing is lost in silence: a damaged chunk, an undecodable or malformed message, a
non-finite value or a truncated file is listed (how many messages, which log-time span) and
the exit status says the analysis is incomplete.

Exit status: 0 analysed, complete; 1 failure at run time (an output could not be written;
no output file is left half written); 2 bad usage or an input that cannot be analysed (one
line on stderr says why); 3 analysed, but incomplete (stderr says what was lost).
"""

import argparse
import concurrent.futures
import contextlib
import csv
from dataclasses import replace
import functools
import json
import math
import multiprocessing
import os
import sys
from typing import (Any, Callable, Dict, List, NamedTuple, Optional, Sequence, TextIO,
                    Tuple)

import numpy as np
from scipy import interpolate

from qrm_ros.core import dynamics as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core import names
from qrm_ros.recording.atomic_files import staged_outputs
from qrm_ros.recording.bag_reader import Loss, open_run, Run, RunFileError
from qrm_ros.analysis.design_table import add_geometry_arguments
from qrm_ros.core.effort_theory import (EFFORT_FIGURES, Setting, steady_effort_theory,
                                        THEORY_FIGURES, ZERO_CAN_BE_EXACT)
from qrm_ros.core.names import (absolute_topic, GEOMETRY_METADATA, JOINT_NAMES, JOINT_STATE_TYPE,
                                MOTOR_DRIVE, PARAMETER_EVENTS_TOPIC, PARAMETERS_METADATA,
                                SIM_NODE_NAME, SPEED_DRIVE)
from qrm_ros.core.units import NANOSECONDS_PER_SECOND
from qrm_ros.core.strokes import find_stroke_pairs, measure_pair_efforts

JOINT_STATES_TOPIC = absolute_topic(names.JOINT_STATES_TOPIC)
PARAMETER_STRING = 4  # rcl_interfaces/msg/ParameterType.PARAMETER_STRING
# The node's parameters that make the drive (Drive): its masses, loads and motor, and which.
DRIVE_PARAMETERS = frozenset(
    ['drive', *(name for kind in dyn.PARAMETER_PREFIXES for name in dyn.parameter_names(kind))])
GEOMETRY_FIELDS = kin.Geometry.field_names()
# Samples whose offset and input speed differ by less than this (relative) are one setting.
STEADY_TOLERANCE = 1e-12
# Shortest steady run worth measuring (a stroke pair needs several samples anyway).
MIN_SEGMENT_SAMPLES = 3
# A step between stamps longer than this many median sample periods is a gap (a pause, a
# clock jump, lost messages): segments end there, so no stroke is measured across it.
GAP_PERIODS = 3.0
EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT, EXIT_INCOMPLETE = 0, 1, 2, 3
EXIT_TRUNCATED = EXIT_INCOMPLETE
# Below this, the between-sample interpolation can miss sharp speed peaks (large offsets).
MIN_SAMPLES_PER_REVOLUTION = 60
PROGRESS_MIN_MESSAGES = 20000
PROGRESS_STEP = 5000
# Very long runs are decoded in parallel worker processes, one per core (up to MAX_WORKERS).
# A worker costs about 0.7 s of CPU to start (its imports); with the block decoding, one
# process reads 360 000 joint states in 1.9 s where two workers took 8.5 s (medians,
# bench_analysis on 2 cores), so only far longer runs are split. Not measured above 1 h.
PARALLEL_MIN_MESSAGES = 2_000_000
MAX_WORKERS = 8
# Read payloads that repeat a learnt layout with numpy (False: rosbags for every message).
FAST_DECODING = True
_BAD_NANOSEC = 'an invalid stamp (nanosec of 10^9 or more)'
# The loss stages: not read from the file at all, read but not usable as a sample, or used
# as a sample without its efforts (the motion kept).
IN_FILE, IN_MESSAGE, IN_EFFORTS = 'file', 'message', 'efforts'
_LOSS_VERBS = {IN_FILE: 'lost', IN_MESSAGE: 'excluded', IN_EFFORTS: 'used without their efforts'}


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


class Lost(NamedTuple):
    """Joint-state messages left out of the analysis, and why (times: s of log time)."""

    stage: str  # IN_FILE: never read; IN_MESSAGE: read but not usable; IN_EFFORTS: see above
    reason: str
    messages: Optional[int]  # None: unknown
    start_time: Optional[float]  # from the recording's first message; None: unknown
    end_time: Optional[float]


class Drive(NamedTuple):
    """The node's mass properties, loads and drive as recorded: the theory of the efforts."""

    mass: dyn.MassProperties
    loads: dyn.Loads
    motor: Optional[dyn.MotorDrive]  # None: the ideal speed drive


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


class DriveSpan(NamedTuple):
    """The mass properties, loads and drive in force from start_time (s, samples' clock) on."""

    start_time: float
    drive: Optional[Drive]
    problem: Optional[str]  # why drive is None


class _Part(NamedTuple):
    """What one worker decoded from its part of the file."""

    stamps: np.ndarray  # ns
    log_times: np.ndarray  # ns
    positions: np.ndarray  # (n, joints) in JOINT_NAMES order
    velocities: np.ndarray
    efforts: np.ndarray  # NaN rows: the message had no efforts
    read: int
    rejected: Dict[str, List[int]]  # reason -> [count, first log time, last log time]
    losses: List[Loss]


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


@functools.lru_cache(maxsize=None)
def _typestore():
    """Return the Jazzy type store, built once (it compiles a decoder per type on first use)."""
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


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
        drive, drive_problem = _drive(stored, geometry)
    except AnalysisError as error:
        if run.truncated:  # say why the topic or the metadata may be missing
            raise AnalysisError(f'{error}; note: {run.problem}') from None
        raise
    total = run.message_count(JOINT_STATES_TOPIC)
    progress = None
    if progress_stream.isatty() and total >= PROGRESS_MIN_MESSAGES:
        progress = _progress(progress_stream, total)  # a bar only for a person, on long files
    workers = min(_usable_cores(), MAX_WORKERS) if total >= PARALLEL_MIN_MESSAGES else 1
    file_parts = run.parts(workers)
    if len(file_parts) == 1:
        parts = [_decode_part(path, file_parts[0], _Counter(), progress, run)]
    else:
        parts = _decode_in_parallel(path, file_parts, progress)
    recording = _combine(path, run, geometry, parts)
    return recording._replace(drive=drive, drive_problem=drive_problem,
                              drive_changes=_drive_changes(run, stored, geometry,
                                                           recording.time_origin_ns))


def _drive_changes(run: Run, stored: Optional[Dict[str, str]],
                   geometry: kin.Geometry, origin_ns: int) -> Tuple[DriveSpan, ...]:
    """
    Return the drives that the node's parameter events put in force mid-run.

    The events are stamped with the node's clock, as the joint states are, so each change
    falls between the two samples it came between. Only the chunks that hold events are
    read again (the file's message indexes say which), so this costs little.
    """
    values, _ = _stored_parameters(stored)
    if values is None or PARAMETER_EVENTS_TOPIC not in run.topics():
        return ()
    spans = []
    store = _typestore()
    for message in run.messages([PARAMETER_EVENTS_TOPIC], on_loss=lambda loss: None):
        try:
            event = store.deserialize_cdr(message.data, message.schema_name)
            changed = [(p.name, _parameter_value(p.value)) for p in event.changed_parameters
                       if p.name in DRIVE_PARAMETERS]
            if event.node.rsplit('/', 1)[-1] != SIM_NODE_NAME or not changed:
                continue
            stamp = event.stamp.sec * NANOSECONDS_PER_SECOND + event.stamp.nanosec
        except Exception:  # noqa: B902 a damaged event is no change we can know of
            continue
        values.update(changed)
        drive, problem = _drive_of_values(values, geometry)
        spans.append(DriveSpan((stamp - origin_ns) / NANOSECONDS_PER_SECOND, drive, problem))
    return tuple(spans)


def _parameter_value(value: Any) -> Any:
    """Return a ParameterValue's scalar (the drive's parameters are doubles and a string)."""
    return value.string_value if value.type == PARAMETER_STRING else value.double_value


def _usable_cores() -> int:
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
    known = _typestore().fielddefs
    for name, definition in recorded.items():
        if name in known and tuple(definition[1]) != tuple(known[name][1]):
            raise AnalysisError(f'{path}: the recorded definition of {name} differs from ROS 2 '
                                'Jazzy\'s; this analysis decodes the standard one only')


def _joint_columns(joint_names: Tuple[str, ...]):
    """Columns of JOINT_NAMES in a message's arrays: None if in order, else an index array."""
    if joint_names == JOINT_NAMES:
        return None
    missing = [joint for joint in JOINT_NAMES if joint not in joint_names]
    if missing:
        return f'the joints {", ".join(missing)} are missing'
    return np.array([joint_names.index(joint) for joint in JOINT_NAMES])


def _reject(rejected: Dict[str, List[int]], reason: str, log_time: int) -> None:
    entry = rejected.setdefault(reason, [0, log_time, log_time])
    entry[0] += 1
    entry[1] = min(entry[1], log_time)
    entry[2] = max(entry[2], log_time)


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


class _Layout(NamedTuple):
    """Where the values sit in joint-state payloads of one size and one set of other bytes."""

    template: np.ndarray  # the payload it was learnt from, as bytes (uint8)
    fixed: np.ndarray  # indices of the bytes every payload of the layout repeats
    sec: slice
    nanosec: slice
    position: slice
    velocity: slice
    effort: Optional[slice]  # None: the payloads have no efforts
    order: Any  # joint columns (None: in JOINT_NAMES order)


def _flipped(array: np.ndarray) -> np.ndarray:
    return (np.ascontiguousarray(array, dtype='<f8').view('<u8') ^ np.uint64(2 ** 64 - 1)
            ).view('<f8')


# Changes making every byte of one value field differ, to find the field by serializing.
_PROBES = {
    'sec': lambda m: replace(m, header=replace(m.header, stamp=replace(
        m.header.stamp, sec=~m.header.stamp.sec))),
    'nanosec': lambda m: replace(m, header=replace(m.header, stamp=replace(
        m.header.stamp, nanosec=m.header.stamp.nanosec ^ 0xFFFFFFFF))),
    'position': lambda m: replace(m, position=_flipped(m.position)),
    'velocity': lambda m: replace(m, velocity=_flipped(m.velocity)),
    'effort': lambda m: replace(m, effort=_flipped(m.effort)),
}


def _learn_layout(data: bytes, decoded: Any, order: Any) -> Optional[_Layout]:
    """
    Find the stamp's, positions', velocities' and efforts' bytes in a payload, by rosbags.

    Each value field is changed in every byte and the message serialized again by rosbags:
    the bytes that differ are that field. Every other byte is structure (lengths, names,
    frame); a payload repeating all of them has the same structure, so rosbags would read
    its values from the same places. None when the payload is not rosbags' own encoding.
    """
    store = _typestore()
    try:
        if bytes(store.serialize_cdr(decoded, JOINT_STATE_TYPE)) != data:
            return None
        original = np.frombuffer(data, dtype=np.uint8)
        regions = {}
        for field, probe in _PROBES.items():
            if field == 'effort' and not len(decoded.effort):
                continue  # no efforts recorded: nothing to find
            changed = np.frombuffer(bytes(store.serialize_cdr(probe(decoded), JOINT_STATE_TYPE)),
                                    dtype=np.uint8)
            if changed.size != original.size:
                return None
            where = np.flatnonzero(changed != original)
            if not where.size or where[-1] - where[0] + 1 != where.size:
                return None
            regions[field] = slice(int(where[0]), int(where[-1]) + 1)
    except Exception:  # rosbags' serializer on a message it decoded: no fast path then
        return None
    stamp = decoded.header.stamp
    if (data[regions['sec']] != np.array([stamp.sec], '<i4').tobytes()
            or data[regions['nanosec']] != np.array([stamp.nanosec], '<u4').tobytes()
            or data[regions['position']] != np.asarray(decoded.position, '<f8').tobytes()
            or data[regions['velocity']] != np.asarray(decoded.velocity, '<f8').tobytes()
            or ('effort' in regions and data[regions['effort']]
                != np.asarray(decoded.effort, '<f8').tobytes())):
        return None
    fixed = np.ones(original.size, dtype=bool)
    for region in regions.values():
        fixed[region] = False
    return _Layout(original, np.flatnonzero(fixed), regions['sec'], regions['nanosec'],
                   regions['position'], regions['velocity'], regions.get('effort'), order)


class _Decoder:
    """
    Joint-state payloads to arrays: rosbags' deserializer, with a vectorised fast path.

    A node publishes the same names and frame every time, so almost every payload repeats a
    learnt layout (see _learn_layout) but for its values: those are read for a whole block
    with numpy. Any other payload goes through rosbags' deserializer, message by message.
    """

    def __init__(self):
        self.deserialize = _typestore().deserialize_cdr
        self.columns: Dict[Tuple[str, ...], Any] = {}
        self.layouts: Dict[int, Optional[_Layout]] = {}
        self.rejected: Dict[str, List[int]] = {}
        self.stamps: List[np.ndarray] = []
        self.log_times: List[np.ndarray] = []
        self.positions: List[np.ndarray] = []
        self.velocities: List[np.ndarray] = []
        self.efforts: List[np.ndarray] = []

    def one(self, data: bytes, log_time: int):
        """Decode one payload with rosbags: (decoded, joint order), or None if rejected."""
        try:
            decoded = self.deserialize(data, JOINT_STATE_TYPE)
        except Exception:  # rosbags raises SerdeError, struct.error, IndexError... on bad bytes
            _reject(self.rejected, 'undecodable CDR payload', log_time)
            return None
        joint_names = tuple(decoded.name)
        order = self.columns.get(joint_names, False)
        if order is False:
            order = self.columns[joint_names] = _joint_columns(joint_names)
        if isinstance(order, str):
            _reject(self.rejected, order, log_time)
            return None
        if len(decoded.position) != len(joint_names) or len(decoded.velocity) != len(
                joint_names):
            _reject(self.rejected, 'fewer or more positions or velocities than joint names',
                    log_time)
            return None
        if len(decoded.effort) not in (0, len(joint_names)):
            _reject(self.rejected, 'efforts neither absent nor one per joint name', log_time)
            return None
        if decoded.header.stamp.nanosec >= NANOSECONDS_PER_SECOND:
            _reject(self.rejected, _BAD_NANOSEC, log_time)
            return None
        return decoded, order

    def block(self, log_times: List[int], payloads: List[bytes]) -> None:
        """Decode a block of payloads (in file order) and keep the usable samples."""
        count = len(payloads)
        width = len(JOINT_NAMES)
        stamps = np.zeros(count, dtype=np.int64)
        positions = np.zeros((count, width))
        velocities = np.zeros((count, width))
        efforts = np.full((count, width), np.nan)
        usable = np.zeros(count, dtype=bool)
        sizes = np.fromiter(map(len, payloads), dtype=np.int64, count=count)
        times = np.array(log_times, dtype=np.int64)
        slow = np.ones(count, dtype=bool)
        if FAST_DECODING:
            for size in np.unique(sizes):
                rows = np.flatnonzero(sizes == size)
                picks = rows[[0, rows.size // 2, -1]]  # a damaged first one does not decide
                layout = self._layout(int(size), [payloads[i] for i in picks])
                if layout is None:
                    continue
                block = np.frombuffer(b''.join([payloads[i] for i in rows]),
                                      dtype=np.uint8).reshape(rows.size, int(size))
                same = (block[:, layout.fixed] == layout.template[layout.fixed]).all(axis=1)
                rows, block = rows[same], block[same]
                slow[rows] = False
                sec = block[:, layout.sec].copy().view('<i4')[:, 0].astype(np.int64)
                nanosec = block[:, layout.nanosec].copy().view('<u4')[:, 0].astype(np.int64)
                columns = slice(None) if layout.order is None else layout.order
                positions[rows] = block[:, layout.position].copy().view('<f8')[:, columns]
                velocities[rows] = block[:, layout.velocity].copy().view('<f8')[:, columns]
                if layout.effort is not None:
                    efforts[rows] = block[:, layout.effort].copy().view('<f8')[:, columns]
                stamps[rows] = sec * NANOSECONDS_PER_SECOND + nanosec
                valid = nanosec < NANOSECONDS_PER_SECOND
                usable[rows[valid]] = True
                for row in rows[~valid]:
                    _reject(self.rejected, _BAD_NANOSEC, int(times[row]))
        for row in np.flatnonzero(slow):
            found = self.one(payloads[row], int(times[row]))
            if found is None:
                continue
            decoded, order = found
            columns = slice(None) if order is None else order
            stamp = decoded.header.stamp
            stamps[row] = stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec
            positions[row] = np.asarray(decoded.position, dtype=float)[columns]
            velocities[row] = np.asarray(decoded.velocity, dtype=float)[columns]
            if len(decoded.effort):
                efforts[row] = np.asarray(decoded.effort, dtype=float)[columns]
            usable[row] = True
        self.stamps.append(stamps[usable])
        self.log_times.append(times[usable])
        self.positions.append(positions[usable])
        self.velocities.append(velocities[usable])
        self.efforts.append(efforts[usable])

    def _layout(self, size: int, candidates: List[bytes]) -> Optional[_Layout]:
        if size not in self.layouts:
            self.layouts[size] = next(filter(None, map(self._learn, candidates)), None)
        return self.layouts[size]

    def _learn(self, data: bytes) -> Optional[_Layout]:
        """Learn a layout from a payload that passes every check (no count kept here)."""
        try:
            decoded = self.deserialize(data, JOINT_STATE_TYPE)
        except Exception:  # as in one(): this payload is not one to learn from
            return None
        joint_names = tuple(decoded.name)
        order = _joint_columns(joint_names)
        if (isinstance(order, str) or len(decoded.position) != len(joint_names)
                or len(decoded.velocity) != len(joint_names)
                or len(decoded.effort) not in (0, len(joint_names))
                or decoded.header.stamp.nanosec >= NANOSECONDS_PER_SECOND):
            return None
        return _learn_layout(data, decoded, order)


def _decode_part(path: str, part: Optional[slice], counter=None, progress=None,
                 run: Optional[Run] = None) -> _Part:
    """Decode the joint states of one part of the file into arrays; list what is unusable."""
    counter = counter or _worker_counter
    decoder = _Decoder()
    losses: List[Loss] = []
    run = run or open_run(path)  # a worker process opens the file itself
    log_times: List[int] = []
    payloads: List[bytes] = []
    count = 0
    for count, message in enumerate(run.messages(  # in file order: the order received
            [JOINT_STATES_TOPIC], log_time_order=False, part=part, on_loss=losses.append), 1):
        log_times.append(message.log_time)
        payloads.append(message.data)
        if count % PROGRESS_STEP == 0:
            decoder.block(log_times, payloads)
            log_times, payloads = [], []
            with counter.get_lock():
                counter.value += PROGRESS_STEP
            if progress is not None:
                progress(counter.value)
    if payloads:
        decoder.block(log_times, payloads)
    if progress is not None:
        progress(run.message_count(JOINT_STATES_TOPIC))
    width = len(JOINT_NAMES)

    def joined(arrays, dtype, shape):
        return np.concatenate(arrays).astype(dtype) if arrays else np.zeros(shape, dtype)
    return _Part(joined(decoder.stamps, np.int64, 0), joined(decoder.log_times, np.int64, 0),
                 joined(decoder.positions, float, (0, width)),
                 joined(decoder.velocities, float, (0, width)),
                 joined(decoder.efforts, float, (0, width)), count, decoder.rejected, losses)


def _decode_in_parallel(path: str, parts: List[Optional[slice]], progress) -> List[_Part]:
    """Decode parts in worker processes (long runs: decoding is per-message Python work)."""
    context = multiprocessing.get_context('spawn')  # no fork of a process that may hold DDS
    counter = context.Value('q', 0)
    with concurrent.futures.ProcessPoolExecutor(len(parts), mp_context=context,
                                                initializer=_start_worker,
                                                initargs=(counter,)) as pool:
        futures = [pool.submit(_decode_part, path, part) for part in parts]
        while not all(future.done() for future in futures):
            concurrent.futures.wait(futures, timeout=0.2)
            if progress is not None:
                progress(min(counter.value, progress.total - 1))
        decoded = [future.result() for future in futures]
    if progress is not None:
        progress(progress.total)
    return decoded


def _seconds(log_time: Optional[int], start: Optional[int]) -> Optional[float]:
    if log_time is None or start is None:
        return None
    return (log_time - start) / NANOSECONDS_PER_SECOND


def _combine(path: str, run: Run, geometry: kin.Geometry, parts: List[_Part]) -> Recording:
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
    finite = np.isfinite(position).all(axis=1) & np.isfinite(velocity).all(axis=1)
    if not finite.all():
        bad = log_times[~finite]
        rejected['non-finite positions or velocities'] = [int(bad.size), int(bad.min()),
                                                          int(bad.max())]
    stamps, log_times = stamps[finite], log_times[finite]
    position, velocity, effort = position[finite], velocity[finite], effort[finite]
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
    if stamps.size < MIN_SEGMENT_SAMPLES:
        raise AnalysisError(f'{path} holds {stamps.size} usable {JOINT_STATES_TOPIC} messages: '
                            'too few to find any stroke' + _loss_clause(losses, run))
    time = (stamps - stamps[0]) / NANOSECONDS_PER_SECOND
    with_efforts = not np.isnan(effort).all()
    samples = Samples(time, position[:, 0], velocity[:, 0], position[:, 1], velocity[:, 1],
                      position[:, 3], velocity[:, 3], position[:, 4], velocity[:, 4],
                      effort[:, 0] if with_efforts else None,
                      effort[:, -1] if with_efforts else None)
    return Recording(path, geometry, samples, run.problem if run.truncated else None,
                     tuple(losses), in_file, read, int((repeat & same).sum()),
                     time_origin_ns=int(stamps[0]))


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


def _drive(stored: Optional[Dict[str, str]],
           geometry: kin.Geometry) -> Tuple[Optional[Drive], Optional[str]]:
    """Read the recorded mass properties, loads and drive; or None and why no theory."""
    values, problem = _stored_parameters(stored)
    if values is None:
        return None, problem
    return _drive_of_values(values, geometry)


def _stored_parameters(stored: Optional[Dict[str, str]]
                       ) -> Tuple[Optional[Dict[str, Any]], Optional[str]]:
    """Return the node's recorded parameter values (JSON in the metadata), or why none."""
    if stored is None:
        return None, f'the file has no {PARAMETERS_METADATA} metadata'
    try:
        return {name: json.loads(text) for name, text in stored.items()}, None
    except ValueError:
        return None, f'the {PARAMETERS_METADATA} metadata is not JSON'


def _drive_of_values(values: Dict[str, Any],
                     geometry: kin.Geometry) -> Tuple[Optional[Drive], Optional[str]]:
    """Make the mass properties, loads and drive of parameter values; or None and why not."""
    drive = values.get('drive', SPEED_DRIVE)
    wanted = {kind: dict(zip(kind.field_names(), dyn.parameter_names(kind)))
              for kind in dyn.PARAMETER_PREFIXES}
    if drive not in (SPEED_DRIVE, MOTOR_DRIVE):
        return None, f'the recorded drive {drive!r} is unknown (expected speed or motor)'
    kinds = [dyn.MassProperties, dyn.Loads] + ([dyn.MotorDrive] if drive == MOTOR_DRIVE
                                               else [])
    missing = [key for kind in kinds for key in wanted[kind].values() if key not in values]
    if missing:
        return None, (f'the {PARAMETERS_METADATA} metadata lacks {", ".join(missing)} '
                      '(recorded before the node had them)')
    try:
        made = [kind(**{name: values[key] for name, key in wanted[kind].items()})
                for kind in kinds]
        made[1].check_against(geometry.ram_stroke)
    except kin.KinematicsError as error:  # DynamicsError is one
        return None, f'the recorded mass properties or loads are refused: {error}'
    return Drive(made[0], made[1], made[2] if drive == MOTOR_DRIVE else None), None


class Segment(NamedTuple):
    start: int  # sample indices, end exclusive
    end: int
    offset: float
    input_speed: float  # rad/s, commanded (setting_speed)
    drive: Optional[Drive] = None  # what drove it (None: no theory of the efforts)


def sample_period(samples: Samples) -> Optional[float]:
    """Return the median step between stamps (s), None with fewer than two samples."""
    steps = np.diff(samples.time)
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else None


def setting_speed(samples: Samples, drive: Optional[Drive] = None) -> np.ndarray:
    """
    Return the input speed each sample was commanded to run at (rad/s).

    The ideal speed drive runs at it. A motor's speed fluctuates about its reference, but
    its torque is k (reference - speed) (dynamics.md), so the reference is the recorded
    speed plus the recorded input torque over k, exact to round-off at every sample. Where
    the motor is at its torque limit the reference is unknown (NaN: no steady setting).
    """
    if drive is None or drive.motor is None or samples.input_torque is None:
        return samples.input_speed
    torque = samples.input_torque
    reference = samples.input_speed + torque / drive.motor.speed_stiffness
    limited = np.abs(torque) >= drive.motor.max_torque * (1.0 - STEADY_TOLERANCE)
    return np.where(limited, np.nan, reference)


def split_segments(samples: Samples, drives: Sequence[DriveSpan] = ()
                   ) -> Tuple[List[Segment], List[Dict[str, Any]]]:
    """
    Split into spans of steady offset and input speed; return (segments, transitions).

    A segment is a maximal run of samples that share one offset, one commanded input speed
    (setting_speed: under a motor, its speed reference) and one drive (drives: the masses,
    loads and drive from when on; none: the ideal speed drive, no theory) with the offset
    actuator at rest (a ramp changes the speed at every sample, so its samples never form a
    run) and no gap between stamps (longer than GAP_PERIODS sample periods, or backwards: a
    pause, a clock jump, lost messages); what lies between segments is a transition,
    excluded from the measurement and reported.
    """
    drives = list(drives) or [DriveSpan(-math.inf, None, None)]
    offset, time = samples.offset, samples.time
    span = np.searchsorted([d.start_time for d in drives], time, side='right') - 1
    span = np.maximum(span, 0)
    speed = np.empty(time.shape)
    for index, drive in enumerate(drives):
        chosen = span == index
        speed[chosen] = setting_speed(samples, drive.drive)[chosen]
    finite = np.abs(speed[np.isfinite(speed)])
    scale = max(1.0, float(np.max(finite))) if finite.size else 1.0
    step = sample_period(samples) or 0.0
    steps = np.diff(time)
    gap = (steps > GAP_PERIODS * step) | (steps < 0)
    changed = ((np.abs(np.diff(offset)) > STEADY_TOLERANCE)
               | ~(np.abs(np.diff(speed)) <= STEADY_TOLERANCE * scale) | gap
               | (np.diff(span) != 0))
    steady = samples.offset_rate == 0.0
    starts = np.flatnonzero(np.concatenate([[True], changed | (steady[1:] != steady[:-1])]))
    ends = np.append(starts[1:], offset.size)
    segments = [Segment(int(a), int(b), float(offset[a]), float(speed[a]),
                        drives[span[a]].drive)
                for a, b in zip(starts, ends) if steady[a] and b - a >= MIN_SEGMENT_SAMPLES]
    transitions = []
    for before, after in zip(segments, segments[1:]):
        changes = []
        jumps = steps[before.end - 1:after.start][gap[before.end - 1:after.start]]
        if jumps.size:
            largest = jumps[np.argmax(np.abs(jumps))]
            changes.append(f'a gap of {largest:.3f} s between stamps (a pause, a clock jump or '
                           'lost messages)' if largest > 0 else
                           f'the clock jumps back by {-largest:.3f} s')
        if after.offset != before.offset:
            changes.append(f'offset {before.offset * 1e3:g} -> {after.offset * 1e3:g} mm')
        if after.input_speed != before.input_speed:
            changes.append(f'input speed {before.input_speed:g} -> {after.input_speed:g} rad/s')
        changes += _drive_differences(before.drive, after.drive)
        transitions.append({
            'kind': 'gap' if jumps.size else 'change',
            'start_time': float(time[before.end - 1]),
            'end_time': float(time[after.start]),
            'offset_from': before.offset, 'offset_to': after.offset,
            'input_speed_from': before.input_speed, 'input_speed_to': after.input_speed,
            'change': ', '.join(changes) or 'interruption'})
    return segments, transitions


def _drive_values(drive: Optional[Drive]) -> Dict[str, Any]:
    """Return a drive as the node's parameter names -> values ({}: no drive known)."""
    if drive is None:
        return {}
    values: Dict[str, Any] = {'drive': SPEED_DRIVE if drive.motor is None else MOTOR_DRIVE}
    for part in (drive.mass, drive.loads, drive.motor):
        if part is not None:
            values.update(zip(dyn.parameter_names(type(part)), part.as_dict().values()))
    return values


def _drive_differences(before: Optional[Drive], after: Optional[Drive]) -> List[str]:
    """Say what changed between two drives, by parameter name ('cutting_force 400 -> 800')."""
    old, new = _drive_values(before), _drive_values(after)
    return [f'{name} {old.get(name, "?")} -> {new.get(name, "?")}'
            for name in sorted(set(old) | set(new)) if old.get(name) != new.get(name)]


def _relative_error(measured: float, theory: float) -> Optional[float]:
    if not (math.isfinite(measured) and math.isfinite(theory)) or theory == 0.0:
        return None
    return measured / theory - 1.0


def _mean_and_spread(values) -> Tuple[Optional[float], Optional[float]]:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return None, None
    spread = float(np.std(values, ddof=1)) if values.size > 1 else 0.0
    return float(np.mean(values)), spread


def flywheel_speed_swing(geometry: kin.Geometry, offset: float) -> float:
    """
    Max / min flywheel speed over a revolution at a steady input speed: the offset's cost.

    Eq. 4: w2 / w1 = r1 (r1 + d sin t) / (r1^2 + d^2 + 2 r1 d sin t) is monotonic in sin t
    for |d| < r1, so its extremes are at sin t = -+1: r1 / (r1 -+ |d|).
    """
    radius = geometry.coupling_radius
    return (radius + abs(offset)) / (radius - abs(offset))


def _speed_extremes(time: np.ndarray, angle: np.ndarray, speed: np.ndarray,
                    starts: np.ndarray, ends: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """
    Max and min of a sampled speed over each [start, end], between samples too.

    The angle is taken as scipy's cubic Hermite interpolant of the sampled angles and speeds
    (its derivative matches every sample), so a peak between samples is found where that
    derivative turns, to O((w dt)^3), not at the nearest sample.
    """
    rate = interpolate.CubicHermiteSpline(time, np.unwrap(angle), speed).derivative()
    turning = rate.derivative().roots(extrapolate=False)
    high, low = np.empty(starts.size), np.empty(starts.size)
    for index, (start, end) in enumerate(zip(starts, ends)):
        inside = np.concatenate([[start, end], turning[(turning > start) & (turning < end)]])
        values = np.concatenate([rate(inside), speed[(time > start) & (time < end)]])
        high[index], low[index] = np.max(values), np.min(values)
    return high, low


class InputTorqueParts(NamedTuple):
    """The speed drive's input torque at a steady setting, split by cause (N m)."""

    total: np.ndarray
    inertia: np.ndarray  # the moving masses' speed changes alone: no gravity, no loads
    cutting: np.ndarray  # the cutting force's share: F_c dx/d(theta) while the tool cuts
    gravity_and_friction: np.ndarray  # the rest: the lever's weight and the ram's friction


def input_torque_parts(geometry: kin.Geometry, drive: Drive, offset: float,
                       input_angle: np.ndarray, input_speed: float) -> InputTorqueParts:
    """
    Split the input torque over input_angle (rad) at a steady input_speed (rad/s) by cause.

    The torque is linear in the masses, in gravity and in the ram force, so the parts add up
    to the total exactly: what the offset costs in inertia torque shows apart from the work.
    """
    motion = kin.state(geometry, offset, input_angle, input_speed)
    loads = drive.loads
    stroke = geometry.ram_stroke

    def torque(mass: dyn.MassProperties, ram_force: Any = 0.0) -> np.ndarray:
        return np.asarray(dyn.efforts(geometry, mass, offset, input_angle, input_speed,
                                      external_ram_force=ram_force).input_torque)
    total = torque(drive.mass, dyn.ram_load_force(loads, motion.ram_position,
                                                  motion.ram_velocity, stroke))
    weightless = dyn.MassProperties(**{**drive.mass.as_dict(), 'gravity': 0.0})
    inertia = torque(weightless)
    cutting_only = dyn.Loads(loads.cutting_force, 0.0, loads.cutting_length)
    cutting = torque(weightless, dyn.ram_load_force(cutting_only, motion.ram_position,
                                                    motion.ram_velocity, stroke)) - inertia
    return InputTorqueParts(total, inertia, cutting, total - inertia - cutting)


def _measured_and_theory(row: Dict[str, Any], name: str, values: np.ndarray,
                         theory: Optional[float]) -> None:
    """Put a figure's mean and spread over pairs, its theory and relative error in row."""
    mean, spread = _mean_and_spread(values)
    row[f'{name}_measured'] = mean
    row[f'{name}_measured_std'] = spread
    row[f'{name}_theory'] = _finite_or_none(theory)
    row[f'{name}_relative_error'] = (None if mean is None or row[f'{name}_theory'] is None
                                     else _relative_error(mean, row[f'{name}_theory']))


def _not_recorded(samples: Samples) -> np.ndarray:
    return np.full(samples.time.shape, np.nan)


def measure_segment(samples: Samples, segment: Segment, geometry: kin.Geometry,
                    drive: Optional[Drive] = None) -> Dict[str, Any]:
    """Measured and theoretical figures of one steady segment, as a JSON-ready dict."""
    span = slice(segment.start, segment.end)
    pairs = find_stroke_pairs(samples.time[span], samples.ram_position[span],
                              samples.ram_velocity[span])
    row: Dict[str, Any] = {
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
    theory: Dict[str, Any] = {name: None for name in measured}
    if segment.input_speed != 0.0 and abs(segment.offset) < geometry.coupling_radius:
        with contextlib.suppress(kin.KinematicsError):  # e.g. a speed too large to be finite
            theory.update(kin.steady_theory(geometry, segment.offset,
                                            segment.input_speed)._asdict())
    for name, values in measured.items():
        _measured_and_theory(row, name, values, theory[name])
    _measure_efforts(row, samples, span, pairs, geometry, drive)
    return row


def _measure_efforts(row: Dict[str, Any], samples: Samples, span: slice, pairs: Any,
                     geometry: kin.Geometry, drive: Optional[Drive]) -> None:
    """Add the drive's figures per pair (efforts, speed fluctuation, flywheel swing) to row."""
    time = samples.time[span]
    torque = samples.input_torque if samples.input_torque is not None else _not_recorded(
        samples)
    force = samples.offset_force if samples.offset_force is not None else _not_recorded(
        samples)
    measured = measure_pair_efforts(time, samples.input_speed[span], torque[span], force[span],
                                    pairs)
    row['stroke_pairs_with_efforts'] = int(np.count_nonzero(
        np.isfinite(measured.energy_per_pair)))
    theory = (dict.fromkeys(THEORY_FIGURES) if drive is None else steady_effort_theory(
        Setting(geometry, drive.mass, drive.loads, drive.motor, row['offset'],
                row['input_speed'])))
    for name in EFFORT_FIGURES:
        _measured_and_theory(row, name, getattr(measured, name), theory[name])
    _measured_and_theory(row, 'speed_fluctuation', measured.speed_fluctuation,
                         theory['speed_fluctuation'])
    for name in ZERO_CAN_BE_EXACT:
        mean, expected = row[f'{name}_measured'], row[f'{name}_theory']
        row[f'{name}_absolute_error'] = (None if mean is None or expected is None
                                         else mean - expected)
    swing = np.empty(0)
    if pairs.cutting_start.size:
        high, low = _speed_extremes(time, samples.flywheel_angle[span],
                                    samples.flywheel_speed[span], pairs.cutting_start,
                                    pairs.return_end)
        # The flywheel turns one way within a pair (w2 / w1 > 0), so |max| / |min| is it.
        swing = np.maximum(np.abs(high), np.abs(low)) / np.minimum(np.abs(high), np.abs(low))
    swing_theory = (flywheel_speed_swing(geometry, row['offset'])
                    if abs(row['offset']) < geometry.coupling_radius else None)
    _measured_and_theory(row, 'flywheel_speed_swing', swing, swing_theory)


class Analysis(NamedTuple):
    recording: Recording
    segments: List[Segment]
    rows: List[Dict[str, Any]]
    transitions: List[Dict[str, Any]]


def analyse(recording: Recording) -> Analysis:
    """Segment the recording and measure every segment against the closed form."""
    with np.errstate(all='ignore'):  # absurd recorded values give inf/NaN, reported as null
        segments, transitions = split_segments(recording.samples, recording.drive_spans())
        rows = [measure_segment(recording.samples, s, recording.geometry, s.drive)
                for s in segments]
    return Analysis(recording, segments, rows, transitions)


def _fmt(value, spec):
    width = spec.lstrip('+-').split('.')[0]
    return format('-', '>' + width) if value is None else format(value, spec)


def format_table(analysis: Analysis) -> str:
    """Return the per-segment table a person reads, with warnings and transitions."""
    recording = analysis.recording
    geometry = recording.geometry
    samples = recording.samples
    span = float(np.ptp(samples.time)) if samples.time.size else 0.0
    lines = [
        f'{recording.path}: {samples.time.size} joint-state samples over {span:.3f} s',
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
    lines += _effort_lines(analysis)
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
    if recording.repeated_stamps:
        lines.append(f'note: {recording.repeated_stamps} messages repeat the previous one '
                     '(same stamp, same values) and were counted once')
    return '\n'.join(lines)


# Rows of the effort block: figure, what it is [unit], value format.
_EFFORT_ROWS = (
    ('peak_input_torque', 'peak |input torque| [N m]', '10.4f'),
    ('rms_input_torque', 'RMS input torque [N m]', '10.4f'),
    ('mean_input_power', 'mean input power [W]', '10.4f'),
    ('energy_per_pair', 'energy per stroke pair [J]', '10.4f'),
    ('peak_offset_force', 'peak |offset force| [N]', '10.3f'),
    ('speed_fluctuation', 'input speed fluctuation Cs [-]', '10.2e'),
    ('flywheel_speed_swing', 'flywheel speed max/min [-]', '10.6f'),
)


def _effort_lines(analysis: Analysis) -> List[str]:
    """Return the drive's figures per segment: measured mean ± s.d., theory, error."""
    recording = analysis.recording
    if not analysis.rows:
        return []
    drive = recording.drive
    lines = ['']
    if drive is None:
        lines.append(f'efforts: no theory ({recording.drive_problem})')
    else:
        kind = ('ideal speed drive' if drive.motor is None else
                f'motor drive, {drive.motor.speed_stiffness:g} N m s/rad, '
                f'{drive.motor.max_torque:g} N m')
        lines.append(f'efforts: theory for the recorded masses and loads, {kind} (cutting '
                     f'{drive.loads.cutting_force:g} N over {drive.loads.cutting_length:g} m, '
                     f'friction {drive.loads.ram_friction:g} N)')
    if recording.samples.input_torque is None:
        lines.append('efforts: not recorded in this file (joint states without effort)')
    for row in analysis.rows:
        lines.append(f'  offset {row["offset"] * 1e3:.2f} mm at {row["input_speed"]:.4f} rad/s, '
                     f'{row["stroke_pairs_with_efforts"]} of {row["stroke_pairs"]} stroke pairs '
                     'with efforts:        measured       theory     error')
        for name, title, spec in _EFFORT_ROWS:
            mean, spread = row[f'{name}_measured'], row[f'{name}_measured_std']
            measured = '-' if mean is None else f'{format(mean, spec)} ± {spread:.1e}'
            if row.get(f'{name}_theory') == 0.0:
                error = _fmt(row[f'{name}_absolute_error'], '+9.1e') + ' (abs.)'
            else:
                error = _fmt(row[f'{name}_relative_error'], '+9.1e')
            lines.append(f'    {title:<32} {measured:>20} {_fmt(row[name + "_theory"], spec)} '
                         f'{error}')
    return lines


def incompleteness(recording: Recording) -> List[str]:
    """Lines saying what the analysis lacks; empty when the recording was read whole."""
    lines = []
    if recording.problem:
        lines.append(f'{recording.path} is damaged or truncated: {recording.problem}')
    for loss in recording.losses:
        count = ('an unknown number of' if loss.messages is None else
                 f'{loss.messages}')
        when = ''
        if loss.start_time is not None:
            when = (f', log time {loss.start_time:.3f} s' + (
                '' if loss.end_time is None else f' to {loss.end_time:.3f} s')
                + ' after the first message')
        verb = _LOSS_VERBS[loss.stage]
        lines.append(f'{count} {JOINT_STATES_TOPIC} messages {verb}{when}: {loss.reason}')
    return lines


def _finite_or_none(value):
    """Map NaN and infinities (and numpy scalars) to JSON-safe values, recursively."""
    if isinstance(value, dict):
        return {key: _finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def to_document(analysis: Analysis) -> Dict[str, Any]:
    """Return the JSON document of an analysis (no NaN or infinity: null instead)."""
    recording = analysis.recording
    return _finite_or_none({
        'file': recording.path,
        'complete': recording.complete,
        'truncated': recording.problem,
        'units': 'SI (m, s, rad, rad/s, m/s); ratios dimensionless',
        'geometry': recording.geometry.as_dict(),
        'messages': {'in_file': recording.messages_in_file, 'read': recording.messages_read,
                     'used': int(recording.samples.time.size),
                     'repeated': recording.repeated_stamps},
        'losses': [loss._asdict() for loss in recording.losses],
        'segments': analysis.rows,
        'transitions': analysis.transitions,
    })


def _write_csv(analysis: Analysis, path: str) -> None:
    fields = list(analysis.rows[0]) if analysis.rows else ['offset']
    with open(path, 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for row in _finite_or_none(analysis.rows):
            writer.writerow({k: ('' if v is None else v) for k, v in row.items()})


def _write_json(analysis: Analysis, path: str) -> None:
    with open(path, 'w') as handle:
        json.dump(to_document(analysis), handle, indent=2, allow_nan=False)
        handle.write('\n')


def write_csv(analysis: Analysis, path: str) -> None:
    """Write the per-segment table as CSV, all or nothing."""
    with staged_outputs() as stage:
        _write_csv(analysis, stage(path))


def write_json(analysis: Analysis, path: str) -> None:
    """Write the results as JSON, all or nothing."""
    with staged_outputs() as stage:
        _write_json(analysis, stage(path))


def write_outputs(analysis: Analysis, csv_path: Optional[str] = None,
                  json_path: Optional[str] = None, plot_folder: Optional[str] = None
                  ) -> List[str]:
    """Write the asked-for outputs together, all or none; return the figure paths."""
    figure_paths: List[str] = []
    created = plot_folder is not None and not os.path.isdir(plot_folder)
    try:
        with staged_outputs() as stage:
            if csv_path:
                _write_csv(analysis, stage(csv_path))
            if json_path:
                _write_json(analysis, stage(json_path))
            if plot_folder:
                os.makedirs(plot_folder, exist_ok=True)
                from qrm_ros.analysis.figures import write_figures
                figure_paths = write_figures(analysis, plot_folder, stage)
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                os.rmdir(plot_folder)  # type: ignore[arg-type]
        raise
    return figure_paths


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
    geometry_group = parser.add_argument_group(
        'geometry', 'override (or supply, for files without it) the stored geometry')
    add_geometry_arguments(geometry_group, defaults=False)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run qrm_analyze; return the exit status (see the module's docstring)."""
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:
        print('qrm_analyze: interrupted; no output file was written', file=sys.stderr)
        return 130
    except Exception as error:  # a last resort: a bug must not print a traceback either
        print(f'qrm_analyze: error: internal failure ({type(error).__name__}: {error}); '
              'please report it with the file', file=sys.stderr)
        return EXIT_FAILURE


def _main(args: argparse.Namespace) -> int:
    overrides = {name: getattr(args, name) for name in GEOMETRY_FIELDS}
    try:
        recording = read_recording(args.run, overrides)
    except AnalysisError as error:
        print(f'qrm_analyze: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    result = analyse(recording)
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
