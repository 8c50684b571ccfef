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
Joint-state payloads of a run file to arrays: rosbags' decoder, with a vectorised fast path.

A node publishes the same joint names and frame every time, so almost every payload repeats
a layout learnt once (which bytes hold the stamp, positions, velocities and efforts): those
are read a block at a time with numpy, the rest message by message through rosbags. What
cannot be used is counted by reason, never dropped in silence. Very long runs are decoded in
worker processes, one part of the file each.
"""

import concurrent.futures
import contextlib
from dataclasses import replace
import functools
import multiprocessing
from typing import Any, Callable, Dict, Iterator, List, NamedTuple, Optional, Tuple

import numpy as np

from qrm_ros.core.common import names
from qrm_ros.core.common.names import (absolute_topic, CRANK_RADIUS_JOINT, JOINT_NAMES,
                                       JOINT_STATE_TYPE)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.bag_reader import Loss, open_run, Run
from qrm_ros.recording.typestore import jazzy_typestore

JOINT_STATES_TOPIC = absolute_topic(names.JOINT_STATES_TOPIC)
PROGRESS_STEP = 5000
# Read payloads that repeat a learnt layout with numpy (False: rosbags for every message).
FAST_DECODING = True
_BAD_NANOSEC = 'an invalid stamp (nanosec of 10^9 or more)'


class DecodedBlock(NamedTuple):
    """The usable joint states of a block of messages, decoded (arrays as in DecodedPart)."""

    stamps: np.ndarray
    log_times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    efforts: np.ndarray
    read: int  # messages in the block, usable or not
    # The crank radius joint's position and velocity (NaN: a message without it).
    crank_radius: Optional[np.ndarray] = None
    crank_radius_rate: Optional[np.ndarray] = None


class DecodedPart(NamedTuple):
    """What one worker decoded from its part of the file."""

    stamps: np.ndarray  # ns
    log_times: np.ndarray  # ns
    positions: np.ndarray  # (n, joints) in JOINT_NAMES order
    velocities: np.ndarray
    efforts: np.ndarray  # NaN rows: the message had no efforts
    read: int
    rejected: Dict[str, List[int]]  # reason -> [count, first log time, last log time]
    losses: List[Loss]
    # The crank radius joint's position and velocity (NaN: a message without it).
    crank_radius: Optional[np.ndarray] = None
    crank_radius_rate: Optional[np.ndarray] = None


@functools.lru_cache(maxsize=None)
def _joint_columns(joint_names: Tuple[str, ...]):
    """Columns of JOINT_NAMES in a message's arrays: None if in order, else an index array."""
    if joint_names == JOINT_NAMES:
        return None
    missing = [joint for joint in JOINT_NAMES if joint not in joint_names]
    if missing:
        return f'the joints {", ".join(missing)} are missing'
    return np.array([joint_names.index(joint) for joint in JOINT_NAMES])


def _crank_column(joint_names: Tuple[str, ...]) -> Optional[int]:
    """Column of the crank radius joint in a message's arrays, None without it."""
    return joint_names.index(CRANK_RADIUS_JOINT) if CRANK_RADIUS_JOINT in joint_names else None


def _reject(rejected: Dict[str, List[int]], reason: str, log_time: int) -> None:
    entry = rejected.setdefault(reason, [0, log_time, log_time])
    entry[0] += 1
    entry[1] = min(entry[1], log_time)
    entry[2] = max(entry[2], log_time)


class MessageCounter:
    """Messages decoded so far (a shared multiprocessing.Value in worker processes)."""

    def __init__(self) -> None:
        self.value = 0

    def get_lock(self) -> contextlib.nullcontext:
        return contextlib.nullcontext()


_worker_counter: Any = None


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
    crank_column: Optional[int] = None  # the crank radius joint's (None: not there)


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
    store = jazzy_typestore()
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
                   regions['position'], regions['velocity'], regions.get('effort'), order,
                   _crank_column(tuple(decoded.name)))


class _Decoder:
    """
    Joint-state payloads to arrays: rosbags' deserializer, with a vectorised fast path.

    A node publishes the same names and frame every time, so almost every payload repeats a
    learnt layout (see _learn_layout) but for its values: those are read for a whole block
    with numpy. Any other payload goes through rosbags' deserializer, message by message.
    """

    def __init__(self, rejected: Optional[Dict[str, List[int]]] = None) -> None:
        self.deserialize = jazzy_typestore().deserialize_cdr
        self.columns: Dict[Tuple[str, ...], Any] = {}
        self.layouts: Dict[int, Optional[_Layout]] = {}
        self.rejected: Dict[str, List[int]] = {} if rejected is None else rejected

    def one(self, data: bytes, log_time: int) -> Optional[Tuple[Any, Any]]:
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

    def block(self, log_times: List[int], payloads: List[bytes]) -> DecodedBlock:
        """Decode a block of payloads (in file order); return the usable samples."""
        count = len(payloads)
        width = len(JOINT_NAMES)
        stamps = np.zeros(count, dtype=np.int64)
        positions = np.zeros((count, width))
        velocities = np.zeros((count, width))
        efforts = np.full((count, width), np.nan)
        radii = np.full(count, np.nan)
        radius_rates = np.full(count, np.nan)
        usable = np.zeros(count, dtype=bool)
        sizes = np.fromiter(map(len, payloads), dtype=np.int64, count=count)
        # MCAP log times are unsigned: one past 2^63 - 1 ns (the year 2262, a damaged value)
        # is held at that, as only the losses' times are told from them.
        times = np.minimum(np.array(log_times, dtype=np.uint64),
                           np.uint64(np.iinfo(np.int64).max)).astype(np.int64)
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
                position = block[:, layout.position].copy().view('<f8')
                velocity = block[:, layout.velocity].copy().view('<f8')
                positions[rows] = position[:, columns]
                velocities[rows] = velocity[:, columns]
                if layout.crank_column is not None:
                    radii[rows] = position[:, layout.crank_column]
                    radius_rates[rows] = velocity[:, layout.crank_column]
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
            crank_column = _crank_column(tuple(decoded.name))
            if crank_column is not None:
                radii[row] = float(decoded.position[crank_column])
                radius_rates[row] = float(decoded.velocity[crank_column])
            if len(decoded.effort):
                efforts[row] = np.asarray(decoded.effort, dtype=float)[columns]
            usable[row] = True
        return DecodedBlock(stamps[usable], times[usable], positions[usable],
                            velocities[usable], efforts[usable], count,
                            radii[usable], radius_rates[usable])

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


def decoded_blocks(run: Run, part: Optional[slice], losses: List[Loss],
                   rejected: Dict[str, List[int]], counter: Any = None,
                   progress: Optional[Callable[[int], None]] = None
                   ) -> Iterator[DecodedBlock]:
    """
    Yield the joint states of one part of the file (None: all) block by block, in file order.

    What cannot be read goes to losses, what is read but unusable to rejected (reason ->
    [count, first log time, last log time]); each block holds at most PROGRESS_STEP messages,
    so a caller that keeps no block runs in memory independent of the run's length.
    """
    counter = counter or MessageCounter()
    decoder = _Decoder(rejected)
    log_times: List[int] = []
    payloads: List[bytes] = []
    for count, message in enumerate(run.messages(  # in file order: the order received
            [JOINT_STATES_TOPIC], log_time_order=False, part=part, on_loss=losses.append), 1):
        log_times.append(message.log_time)
        payloads.append(message.data)
        if count % PROGRESS_STEP == 0:
            yield decoder.block(log_times, payloads)
            log_times, payloads = [], []
            with counter.get_lock():
                counter.value += PROGRESS_STEP
            if progress is not None:
                progress(counter.value)
    if payloads:
        yield decoder.block(log_times, payloads)


def decode_part(path: str, part: Optional[slice], counter: Any = None,
                progress: Optional[Callable[[int], None]] = None,
                run: Optional[Run] = None) -> DecodedPart:
    """Decode the joint states of one part of the file into arrays; list what is unusable."""
    losses: List[Loss] = []
    rejected: Dict[str, List[int]] = {}
    run = run or open_run(path)  # a worker process opens the file itself
    blocks = list(decoded_blocks(run, part, losses, rejected, counter or _worker_counter,
                                 progress))
    if progress is not None:
        progress(run.message_count(JOINT_STATES_TOPIC))
    width = len(JOINT_NAMES)

    def joined(arrays, dtype, shape):
        return np.concatenate(arrays).astype(dtype) if arrays else np.zeros(shape, dtype)
    return DecodedPart(joined([b.stamps for b in blocks], np.int64, 0),
                       joined([b.log_times for b in blocks], np.int64, 0),
                       joined([b.positions for b in blocks], float, (0, width)),
                       joined([b.velocities for b in blocks], float, (0, width)),
                       joined([b.efforts for b in blocks], float, (0, width)),
                       sum(b.read for b in blocks), rejected, losses,
                       joined([b.crank_radius for b in blocks], float, 0),
                       joined([b.crank_radius_rate for b in blocks], float, 0))


def decode_in_parallel(path: str, parts: List[Optional[slice]],
                       progress: Optional[Any]) -> List[DecodedPart]:
    """Decode parts in worker processes (long runs: decoding is per-message Python work)."""
    context = multiprocessing.get_context('spawn')  # no fork of a process that may hold DDS
    counter = context.Value('q', 0)
    with concurrent.futures.ProcessPoolExecutor(len(parts), mp_context=context,
                                                initializer=_start_worker,
                                                initargs=(counter,)) as pool:
        futures = [pool.submit(decode_part, path, part) for part in parts]
        while not all(future.done() for future in futures):
            concurrent.futures.wait(futures, timeout=0.2)
            if progress is not None:
                progress(min(counter.value, progress.total - 1))
        decoded = [future.result() for future in futures]
    if progress is not None:
        progress(progress.total)
    return decoded
