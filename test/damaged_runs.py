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
A seeded generator of damaged and odd recordings, for the fuzz tests (test_fuzz.py).

Two families, both starting from the golden logs:
- byte damage, which the file's CRCs and framing must catch: bit flips, overwritten, zeroed
  and cut ranges, garbage, huge length fields;
- rewrites through the mcap Writer (joint states only, the other topics' channels kept
  without messages, to keep the suite fast), so every CRC is right and the damage reaches
  the CDR decoder and the analysis: undecodable payloads, wrong schemas and message types, bad
  metadata values, odd timestamps, non-finite values, arrays that do not match the names,
  single-bit flips of joint values (the lever's and, in logs given the crank radius joint,
  the crank radius's too) and of stamps (header or log time) that only the physics can
  see, and runs decimated to a coarse sampling.
Values just inside the singular limits are test_qrm_analyze_hostile_runs.py's (synthetic runs).
Each case knows how many joint-state messages its file holds and which exit codes of
``qrm_analyze`` are acceptable for it.
"""

import functools
import io
import math
import random
import struct
from typing import Callable, Dict, FrozenSet, List, NamedTuple, Optional

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
import numpy as np
from rosbags.typesys import get_typestore, Stores

from qrm_ros.analysis.measurement import ALL_BOUNDED_FIGURES
from qrm_ros.analysis.report import MISSED_STROKE_TURNS, sampling_relative_bound
from qrm_ros.core.common.names import CRANK_RADIUS_JOINT, GEOMETRY_METADATA, JOINT_STATE_TYPE
from qrm_ros.core.measurement.sampling_bounds import SUPPORTED_RELATIVE_ERROR

JOINT_STATES = '/joint_states'
ANY_OUTCOME = frozenset({0, 2, 3})
INCOMPLETE = frozenset({2, 3})  # 2 when nothing usable is left
REFUSED = frozenset({2})
GAP = frozenset({0})  # a pause or a clock jump: complete, with a gap listed


def assert_supported(segments, constant_speed, context):
    """Check an analysis that exited 0: every figure supported to 1e-3 by the sampling.

    At a constant input speed (the speed drive), each figure must also lie within its stated
    bound of the closed form: the bound is true.
    """
    for segment in segments:
        for name in ALL_BOUNDED_FIGURES:
            measured, theory = segment[f'{name}_measured'], segment[f'{name}_theory']
            if measured is None:
                continue
            bound = segment[f'{name}_sampling_bound']
            relative = sampling_relative_bound(segment, name)
            assert bound is not None and relative is not None and (
                relative <= SUPPORTED_RELATIVE_ERROR), (name, segment['offset'], context)
            if constant_speed and theory is not None:
                assert abs(measured - theory) <= bound + 1e-9 * abs(theory), (
                    name, segment['offset'], measured, theory, bound, context)


def incomplete_or_unsupported(document):
    """Say whether an analysis' JSON shows why it exited 3.

    Data left out, a theory missing, or a figure the sampling does not support.
    """
    if not document['complete']:
        return True
    for segment in document['segments']:
        if segment.get('misplaced_stamps') or segment.get('effort_theory_problem'):
            return True
        turns = (abs(segment['input_speed']) * (segment['end_time'] - segment['start_time'])
                 / (2 * math.pi))
        if segment['stroke_pairs'] == 0 and turns >= MISSED_STROKE_TURNS:
            return True
        for name in ALL_BOUNDED_FIGURES:
            relative = sampling_relative_bound(segment, name)
            if segment[f'{name}_measured'] is not None and (
                    relative is None or relative > SUPPORTED_RELATIVE_ERROR):
                return True
    return False


class Case(NamedTuple):
    name: str
    data: bytes
    messages: int  # joint-state messages in the file before byte damage
    allowed: FrozenSet[int]  # acceptable exit codes of qrm_analyze
    same_results: bool = False  # the analysis must equal the undamaged log's
    gap: bool = False  # a pause or clock jump inside the run: a gap must be listed


@functools.lru_cache(maxsize=None)
def _store():
    return get_typestore(Stores.ROS2_JAZZY)


class Recorded(NamedTuple):
    """A log taken apart: what the mcap Writer needs to write it again."""

    schemas: Dict[int, tuple]  # id -> (name, encoding, data)
    channels: Dict[int, tuple]  # id -> (topic, message encoding, schema id, metadata)
    metadata: Dict[str, Dict[str, str]]
    messages: List[list]  # [channel id, log time, publish time, sequence, data], file order
    joint_channel: int

    def joint_states(self):
        return [m for m in self.messages if m[0] == self.joint_channel]


def take_apart(data: bytes) -> Recorded:
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    schemas = {i: (s.name, s.encoding, s.data) for i, s in summary.schemas.items()}
    channels = {i: (c.topic, c.message_encoding, c.schema_id, dict(c.metadata))
                for i, c in summary.channels.items()}
    metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    messages = [[m.channel_id, m.log_time, m.publish_time, m.sequence, m.data]
                for _, _, m in reader.iter_messages(log_time_order=False)]
    joint = next(i for i, c in channels.items() if c[0] == JOINT_STATES)
    return Recorded(schemas, channels, metadata, messages, joint)


def put_together(recorded: Recorded, chunk_size: int = 32 * 1024) -> bytes:
    stream = io.BytesIO()
    writer = Writer(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    writer.start('ros2', 'qrm_ros test damaged_runs')
    schema_ids = {i: writer.register_schema(*s) for i, s in recorded.schemas.items()}
    channel_ids = {i: writer.register_channel(topic, encoding, schema_ids[schema], metadata)
                   for i, (topic, encoding, schema, metadata) in recorded.channels.items()}
    for name, values in recorded.metadata.items():
        writer.add_metadata(name, values)
    for channel, log_time, publish_time, sequence, data in recorded.messages:
        writer.add_message(channel_ids[channel], log_time, bytes(data), publish_time, sequence)
    writer.finish()
    return stream.getvalue()


def decode_joint_state(data):
    """Return a recorded JointState's CDR bytes as a message whose arrays may be changed."""
    decoded = _store().deserialize_cdr(bytes(data), JOINT_STATE_TYPE)
    decoded.position, decoded.velocity = decoded.position.copy(), decoded.velocity.copy()
    return decoded


def encode_joint_state(message):
    """Return a JointState message as CDR bytes, as the recorder writes it."""
    return bytes(_store().serialize_cdr(message, JOINT_STATE_TYPE))


# --- byte damage ---------------------------------------------------------------------------

def _top_level_records(data: bytes):
    """Return (offset, opcode, length) of the records after the magic, as far as they parse."""
    found, offset = [], 8
    while offset + 9 <= len(data):
        opcode, length = struct.unpack_from('<BQ', data, offset)
        found.append((offset, opcode, length))
        offset += 9 + length
    return found


def bit_flips(rng, data):
    damaged = bytearray(data)
    for _ in range(rng.randint(1, 3)):
        damaged[rng.randrange(8, len(damaged))] ^= 1 << rng.randrange(8)
    return bytes(damaged)


def range_overwrite(rng, data):
    damaged = bytearray(data)
    start = rng.randrange(8, len(damaged))
    length = min(rng.randint(1, 256), len(damaged) - start)
    damaged[start:start + length] = rng.randbytes(length)
    return bytes(damaged)


def zeroed_range(rng, data):
    damaged = bytearray(data)
    start = rng.randrange(8, len(damaged))
    length = min(rng.randint(1, 4096), len(damaged) - start)
    damaged[start:start + length] = bytes(length)
    return bytes(damaged)


def truncation(rng, data):
    return data[:rng.randrange(0, len(data))]


def garbage(rng, data):
    body = rng.randbytes(rng.randint(0, 4096))
    return (data[:8] + body) if rng.random() < 0.7 else body


def huge_length(rng, data):
    records = _top_level_records(data)
    offset, opcode, _ = rng.choice(records)
    huge = rng.choice([2 ** 64 - 1, 2 ** 63, 2 ** 40, 4 * 2 ** 30 - 1, len(data) * 2, 0])
    damaged = bytearray(data)
    if opcode == 0x06 and rng.random() < 0.6:  # inside a chunk: sizes and string lengths
        field = rng.choice([(9 + 16, '<Q'), (9 + 28, '<I')])  # uncompressed size, compression
        struct.pack_into(field[1], damaged, offset + field[0], huge % (2 ** (8 * struct.calcsize(
            field[1]))))
    else:
        struct.pack_into('<Q', damaged, offset + 1, huge)
    return bytes(damaged)


BYTE_DAMAGE = [bit_flips, range_overwrite, zeroed_range, truncation, garbage, huge_length]


# --- rewrites with every CRC right ---------------------------------------------------------

def _pick(rng, items, most=5):
    return rng.sample(items, rng.randint(1, min(most, len(items))))


def cdr_payload(rng, recorded):
    for message in _pick(rng, recorded.joint_states()):
        data = message[4]
        how = rng.randrange(4)
        if how == 0:
            message[4] = data[:rng.randrange(len(data))]
        elif how == 1:
            message[4] = rng.randbytes(len(data))
        elif how == 2:  # a sequence length far beyond the payload
            at = rng.randrange(4, len(data) - 4)
            message[4] = data[:at] + struct.pack('<I', rng.choice([2 ** 32 - 1, 2 ** 20])) \
                + data[at + 4:]
        else:
            message[4] = data + rng.randbytes(rng.randint(1, 64))  # trailing bytes: harmless
    # A changed length or random bytes may still decode (as other values): any exit status,
    # but the counts must still add up.
    return ANY_OUTCOME


def wrong_schema(rng, recorded):
    name, encoding, data = recorded.schemas[recorded.channels[recorded.joint_channel][2]]
    topic, message_encoding, schema_id, metadata = recorded.channels[recorded.joint_channel]
    how = rng.randrange(6)
    if how == 0:
        recorded.schemas[schema_id] = ('sensor_msgs/msg/JointStates', encoding, data)
    elif how == 1:
        recorded.schemas[schema_id] = (name, encoding, data.replace(b'float64[] position',
                                                                    b'float32[] position'))
    elif how == 2:
        recorded.channels[recorded.joint_channel] = (topic, 'json', schema_id, metadata)
    elif how == 3:
        recorded.channels[recorded.joint_channel] = ('/joint_state', message_encoding,
                                                     schema_id, metadata)
    elif how == 4:
        recorded.schemas[schema_id] = (name, 'jsonschema', data)
    else:
        recorded.schemas[schema_id] = (name, encoding, rng.randbytes(len(data)))
    return REFUSED


def bad_metadata(rng, recorded):
    geometry = recorded.metadata.setdefault(GEOMETRY_METADATA, {})
    key = rng.choice(sorted(set(geometry) - {'crank_phase'}))  # a phase may be 0 or negative
    how = rng.randrange(3)
    if how == 0:
        geometry[key] = rng.choice(['nan', 'inf', '-inf', '-0.01', 'abc', '', '1e400', '0',
                                    '0x1p-3', '\u00bd'])
    elif how == 1:
        del geometry[key]
    else:
        geometry['crank_radius'] = repr(float(geometry['pivot_distance']) * 1.5)
    # ('0x1p-3' and '½' are no float literals Python reads: every value above is refused.)
    return REFUSED


def _rewrite_joint_states(recorded, change, targets=None):
    for message in recorded.joint_states() if targets is None else targets:
        decoded = decode_joint_state(message[4])
        if change(decoded, message) is not False:
            message[4] = encode_joint_state(decoded)


def odd_timestamps(rng, recorded):
    joints = recorded.joint_states()
    start = rng.randrange(len(joints) // 4, 3 * len(joints) // 4)
    how = rng.randrange(6)
    if how in (0, 1):  # a pause (forward jump) or a clock jump back, from one message on
        shift = int((3.0 if how == 0 else -2.0) * 1e9)
        later = {id(m) for m in joints[start:]}

        def move(decoded, message):
            if id(message) not in later:
                return False
            ns = decoded.header.stamp.sec * 10 ** 9 + decoded.header.stamp.nanosec + shift
            decoded.header.stamp.sec, decoded.header.stamp.nanosec = divmod(ns, 10 ** 9)
        _rewrite_joint_states(recorded, move, joints[start:])
        return GAP
    picked = _pick(rng, joints)
    chosen = {id(m) for m in picked}
    if how == 2:
        def odd(decoded, message):
            if id(message) not in chosen:
                return False
            decoded.header.stamp.nanosec = rng.choice([10 ** 9, 2 ** 32 - 1])
        _rewrite_joint_states(recorded, odd, picked)
        return INCOMPLETE
    if how == 3:
        def extreme(decoded, message):
            if id(message) not in chosen:
                return False
            decoded.header.stamp.sec = rng.choice([0, -2 ** 31, 2 ** 31 - 1])
        _rewrite_joint_states(recorded, extreme, picked)
        return frozenset({0, 3})
    index = recorded.messages.index(joints[start])
    copy = list(recorded.messages[index])
    if how == 5:  # same stamp, other values: conflicting
        decoded = decode_joint_state(copy[4])
        decoded.position[3] += 1e-3
        copy[4] = encode_joint_state(decoded)
    recorded.messages.insert(index + 1, copy)
    return frozenset({0}) if how == 4 else INCOMPLETE


def non_finite(rng, recorded):
    if rng.random() < 0.2:  # an infinite input speed everywhere: nothing usable
        def everywhere(decoded, message):
            decoded.velocity[0] = math.inf
        _rewrite_joint_states(recorded, everywhere)
        return REFUSED
    picked = _pick(rng, recorded.joint_states())
    chosen = {id(m) for m in picked}

    def spoil(decoded, message):
        if id(message) not in chosen:
            return False
        array = decoded.position if rng.random() < 0.5 else decoded.velocity
        array[rng.randrange(len(array))] = rng.choice([math.nan, math.inf, -math.inf])
    _rewrite_joint_states(recorded, spoil, picked)
    return INCOMPLETE


def odd_arrays(rng, recorded):
    how = rng.randrange(4)
    if how == 3:  # joints in another order, arrays to match: a valid message
        order = list(range(5))
        rng.shuffle(order)

        def permute(decoded, message):
            order[5:] = range(5, len(decoded.name))  # the crank radius's joint, if recorded
            decoded.name = [decoded.name[i] for i in order]
            decoded.position = decoded.position[order]
            decoded.velocity = decoded.velocity[order]
            if len(decoded.effort):
                decoded.effort = decoded.effort[order]
        _rewrite_joint_states(recorded, permute)
        return None
    picked = _pick(rng, recorded.joint_states())
    chosen = {id(m) for m in picked}

    def spoil(decoded, message):
        if id(message) not in chosen:
            return False
        if how == 0:
            decoded.position = decoded.position[:rng.randrange(len(decoded.position))]
        elif how == 1:
            decoded.velocity = decoded.velocity[:0]
        else:
            dropped = rng.choice(decoded.name)
            decoded.name = [n for n in decoded.name if n != dropped]
    _rewrite_joint_states(recorded, spoil, picked)
    return INCOMPLETE


def flip_bit(value, bit):
    """Return value (a float) with one bit of its IEEE 754 double flipped."""
    (bits,) = struct.unpack('<Q', struct.pack('<d', value))
    return struct.unpack('<d', struct.pack('<Q', bits ^ (1 << bit)))[0]


# The joint values the closed form ties together (positions: input, flywheel, lever, ram,
# offset and the crank radius joint's when recorded; velocities: input, flywheel, lever, ram,
# and the crank radius's rate): a change in any is caught by the physics.
TIED_POSITIONS, TIED_VELOCITIES = (0, 1, 2, 3, 4, 5), (0, 1, 2, 3, 5)


def with_crank_radius_joint(recorded):
    """Give every joint state the crank radius joint, at the geometry's radius and at rest.

    As the node publishes it now (six joints): the speed-drive golden logs predate it (the
    motor log has it already, and is left as it is).
    """
    radius = float(recorded.metadata[GEOMETRY_METADATA]['crank_radius'])

    def add(decoded, message):
        if CRANK_RADIUS_JOINT in decoded.name:
            return False
        decoded.name = list(decoded.name) + [CRANK_RADIUS_JOINT]
        decoded.position = np.append(decoded.position, radius)
        decoded.velocity = np.append(decoded.velocity, 0.0)
        if len(decoded.effort):
            decoded.effort = np.append(decoded.effort, 0.0)
    _rewrite_joint_states(recorded, add)


def value_flips(rng, recorded):
    """Flip one bit of one joint value in a few messages: no CRC sees it (re-encoded)."""
    if rng.random() < 0.5:
        with_crank_radius_joint(recorded)
    picked = _pick(rng, recorded.joint_states())
    chosen = {id(m) for m in picked}

    def flip(decoded, message):
        if id(message) not in chosen:
            return False
        joints = len(decoded.position)
        places = [(decoded.position, i) for i in TIED_POSITIONS
                  if i < joints and decoded.position[i]]
        places += [(decoded.velocity, i) for i in TIED_VELOCITIES
                   if i < joints and decoded.velocity[i]]
        array, index = rng.choice(places)
        # A high mantissa or low exponent bit: at least 1/128 of the value, never round-off.
        array[index] = flip_bit(float(array[index]), rng.randrange(45, 58))
    _rewrite_joint_states(recorded, flip, picked)
    return INCOMPLETE


def foreign_geometry(rng, recorded):
    """
    Name in the metadata another valid geometry than the one the run was made with.

    A run that records the crank radius's joint (made since the stroke adjustment) is
    analysed with the recorded radius, the metadata's being the start-up value: another
    crank_radius there changes no result.
    """
    geometry = recorded.metadata.setdefault(GEOMETRY_METADATA, {})
    key = rng.choice(['crank_radius', 'pivot_distance', 'ram_height', 'coupling_radius'])
    geometry[key] = repr(float(geometry[key]) * rng.choice([0.9, 1.05, 1.2]))
    if key == 'crank_radius' and CRANK_RADIUS_JOINT in decode_joint_state(
            recorded.joint_states()[0][-1]).name:
        return None
    return REFUSED


def stamp_flips(rng, recorded):
    """Flip one bit of a header stamp (sec or nanosec) or of the log time in a few messages.

    Whatever the analysis makes of it (a gap, a jump back, an invalid stamp excluded), the
    figures it calls complete must be supported (checked by the test on exit 0).
    """
    picked = _pick(rng, recorded.joint_states(), most=3)
    chosen = {id(m) for m in picked}
    where = rng.choice(['sec', 'nanosec', 'log_time'])
    if where == 'log_time':
        for message in picked:
            message[1] ^= 1 << rng.randrange(0, 64)
        return frozenset({0, 3})

    def flip(decoded, message):
        if id(message) not in chosen:
            return False
        stamp = decoded.header.stamp
        if where == 'sec':  # int32
            stamp.sec = struct.unpack('<i', struct.pack('<I', (stamp.sec & 0xFFFFFFFF)
                                                        ^ (1 << rng.randrange(32))))[0]
        else:  # uint32
            stamp.nanosec ^= 1 << rng.randrange(32)
    _rewrite_joint_states(recorded, flip, picked)
    return frozenset({0, 3})


def decimation(rng, recorded):
    """Keep every k-th joint state only (a recorder that dropped most of them, evenly)."""
    every = rng.choice([2, 4, 10, 40])
    joints = {id(m) for m in recorded.joint_states()[1::every]}
    recorded.messages[:] = [m for m in recorded.messages
                            if m[0] != recorded.joint_channel or id(m) not in joints]
    return frozenset({0, 3})


REWRITES = [cdr_payload, wrong_schema, bad_metadata, odd_timestamps, non_finite, odd_arrays,
            value_flips, foreign_geometry, stamp_flips, decimation]


def cases(logs: Dict[str, bytes], count: int, seed: int) -> List[Case]:
    """Return `count` cases, the same for the same seed, over every class and log."""
    rng = random.Random(seed)
    names = sorted(logs)
    apart = {name: take_apart(logs[name]) for name in names}
    kinds: List[Callable] = BYTE_DAMAGE + REWRITES
    made = []
    for number in range(count):
        kind = kinds[number % len(kinds)]
        log = names[(number // len(kinds)) % len(names)]
        label = f'{number}-{kind.__name__}-{log}'
        messages = len(apart[log].joint_states())
        if kind in BYTE_DAMAGE:
            made.append(Case(label, kind(rng, logs[log]), messages, ANY_OUTCOME))
            continue
        original = apart[log]
        recorded = Recorded(dict(original.schemas), dict(original.channels),
                            {k: dict(v) for k, v in original.metadata.items()},
                            # every message: the parameter events say what changed mid-run
                            [list(m) for m in original.messages], original.joint_channel)
        allowed: Optional[FrozenSet[int]] = kind(rng, recorded)
        made.append(Case(label, put_together(recorded), len(recorded.joint_states()),
                         allowed or frozenset({0}), same_results=allowed is None,
                         gap=allowed is GAP))
    return made
