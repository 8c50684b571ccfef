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
Two recorded runs compared field by field, bit for bit or within ulps: where they first differ.

A test that reproduces a run (the simulator on another machine, a node after a change) wants
to know whether it gives the same numbers, and if not, which number first. The messages are
paired by topic and index and compared by their decoded fields, never by their bytes: the
padding rclpy leaves in a CDR message, and the bytes past its end, are undefined. The first
run is streamed in log-time order and the second topic by topic beside it, so a run of a
million messages is compared in the memory of a few chunks.
"""

import dataclasses
import math
import os
import struct
from typing import Any, Dict, Iterable, Iterator, List, NamedTuple, Optional, Tuple, Union

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import get_types_from_idl, get_types_from_msg, get_typestore, Stores

from qrm_ros.core.common.names import absolute_topic
from qrm_ros.recording.bag_reader import MessageTuple, open_run, Run, RunFileError, Topics
from qrm_ros.recording.mcap_structure import describe_error
from qrm_ros.recording.typestore import jazzy_typestore

__all__ = ['LOG_TIME', 'MESSAGE_COUNT', 'MESSAGE_TYPE', 'RunDifference', 'RunSource',
           'assert_runs_match', 'first_difference', 'ulp_distance']

# A run: the path of its file, or the Run that open_run made of it.
RunSource = Union[str, 'os.PathLike[str]', Run]
# The `field` of a difference that is no field of a message (a field's name has no space).
MESSAGE_TYPE = 'message type'
MESSAGE_COUNT = 'message count'
LOG_TIME = 'log time'
# The type whose `stamp` header_stamps=False leaves out, wherever a message holds one.
HEADER_TYPE = 'std_msgs/msg/Header'
# Bits of the IEEE floats of the message definitions.
FLOAT_WIDTHS = {'float64': 64, 'float32': 32}
# The first two bytes of a CDR message: plain CDR, big or little endian.
CDR_ENCAPSULATIONS = (b'\x00\x00', b'\x00\x01')
# Characters of a long string shown around the place where two strings differ.
STRING_CONTEXT = 30


def ulp_distance(first: Union[float, np.floating], second: Union[float, np.floating]
                 ) -> Optional[int]:
    """
    Return how many units in the last place apart two floats are; None if not comparable.

    Counted on the ordered integers of the IEEE bits (float32 ones when both are
    numpy.float32, doubles otherwise), so across zero and through the subnormals alike; the two
    zeros are 0 apart. A NaN or an infinity is 0 from itself (the same bits) and None from
    anything else: it is within no number of ulps of it.
    """
    width = _width(first, second)
    first_bits, second_bits = _bits(first, width), _bits(second, width)
    if first_bits == second_bits:
        return 0
    if not (math.isfinite(first) and math.isfinite(second)):
        return None
    return abs(_ordered(first_bits, width) - _ordered(second_bits, width))


def _width(first: Union[float, np.floating], second: Union[float, np.floating]) -> int:
    """Return the bits of the floats compared: 32 for two numpy.float32, else 64."""
    return 32 if isinstance(first, np.float32) and isinstance(second, np.float32) else 64


def _bits(value: Union[float, np.floating], width: int) -> int:
    """Return a float's IEEE bits as an unsigned integer (float32's when width is 32)."""
    code, unsigned = ('<f', '<I') if width == 32 else ('<d', '<Q')
    return struct.unpack(unsigned, struct.pack(code, value))[0]


def _ordered(bits: int, width: int) -> int:
    """Return the float's place on the number line: sign and magnitude made one integer."""
    sign = 1 << (width - 1)
    return -(bits ^ sign) if bits & sign else bits


def _floats_match(first: Union[float, np.floating], second: Union[float, np.floating],
                  ulps: int) -> bool:
    """Whether two floats are the same bits or, with ulps > 0, at most ulps apart."""
    width = _width(first, second)
    if _bits(first, width) == _bits(second, width):
        return True
    distance = ulp_distance(first, second)
    return ulps > 0 and distance is not None and distance <= ulps


class RunDifference(NamedTuple):
    """Where two runs first differ; str() says it in words a failed test can print."""

    topic: str
    message_index: Optional[int]  # on its topic, from 0; None: the topic as a whole
    log_time: Optional[int]  # ns, of that message in the first run (the second's if only there)
    field: str  # a path such as 'status[0].values[5].value', or MESSAGE_TYPE, ..., LOG_TIME
    first: Any  # the value in the first run: a float64 field's a float, a float32's a np.float32
    second: Any  # the value in the second run; None where a run has no such topic
    ulps_apart: Optional[int] = None  # two floats' ulp_distance

    def __str__(self) -> str:
        if self.field == MESSAGE_TYPE:
            if self.first is None or self.second is None:
                return (f'{self.topic} ({self.first or self.second}) is in the '
                        f'{"first" if self.second is None else "second"} run only')
            return (f'{self.topic} is of type {self.first} in the first run, {self.second} in '
                    'the second')
        where = f'{self.topic} message {self.message_index} (log time {self.log_time} ns)'
        if self.field == MESSAGE_COUNT:
            return (f'{self.topic} has {self.first} messages in the first run, {self.second} '
                    f'in the second: {where} is in the '
                    f'{"first" if self.first > self.second else "second"} run only')
        if self.field == LOG_TIME:
            return (f'{self.topic} message {self.message_index}: log time {self.first} ns in '
                    f'the first run, {self.second} ns in the second')
        first, second = _value_texts(self.first, self.second)
        return (f'{where}: {self.field} is {first} in the first run, {second} in the second'
                + _apart_text(self.first, self.second, self.ulps_apart))


def _value_texts(first: Any, second: Any) -> Tuple[str, str]:
    """Write two differing values: floats by repr, long strings around where they differ."""
    if (isinstance(first, str) and isinstance(second, str)
            and max(len(first), len(second)) > 2 * STRING_CONTEXT):
        at = next((i for i, (a, b) in enumerate(zip(first, second)) if a != b),
                  min(len(first), len(second)))
        return _excerpt(first, at), _excerpt(second, at)
    return _value_text(first), _value_text(second)


def _excerpt(text: str, at: int) -> str:
    """Write the part of a long string around character `at`, where it differs."""
    start, end = max(at - STRING_CONTEXT, 0), at + STRING_CONTEXT
    return (f'{"..." if start else ""}{text[start:end]!r}{"..." if end < len(text) else ""} '
            f'({len(text)} characters, the first different at {at})')


def _value_text(value: Any) -> str:
    """Write one value; a NaN with its bits, since NaNs of different bits differ."""
    if isinstance(value, np.float32):
        text = str(value)  # the shortest digits that read back as this float32
        return f'{text} (bits {_bits(value, 32):#010x})' if math.isnan(value) else text
    if isinstance(value, float):
        return f'nan (bits {_bits(value, 64):#018x})' if math.isnan(value) else repr(value)
    return repr(value)


def _apart_text(first: Any, second: Any, ulps_apart: Optional[int]) -> str:
    """Say how far apart two differing floats are, or why they are not within any ulps."""
    if not isinstance(first, (float, np.float32)):
        return ''
    unit = 'float32 ulp' if isinstance(first, np.float32) else 'ulp'
    if ulps_apart == 0:
        return f' (0 {unit}s apart, but not bit for bit: zeros of opposite sign)'
    if ulps_apart is not None:
        return f' ({ulps_apart} {unit}{"" if ulps_apart == 1 else "s"} apart)'
    if math.isnan(first) and math.isnan(second):
        return ' (NaNs of different bits)'
    if math.isnan(first) or math.isnan(second):
        return ' (a NaN is within no ulps of a number)'
    return ' (an infinity equals only itself)'


class _Field(NamedTuple):
    """One field of a message definition, as the comparison walks it."""

    name: str  # as the definition spells it
    attribute: str  # as rosbags' message class holds it (a Python keyword gains a '_')
    type_name: str  # a base type ('float64', 'string', ...) or a message type
    message: bool  # whether type_name is a message type
    sequence: bool  # an array or a sequence of type_name


class _FieldDifference(NamedTuple):
    """The first field of two decoded messages that differs."""

    field: str
    first: Any
    second: Any
    ulps_apart: Optional[int]


def _plain(value: Any) -> Any:
    """Return a numpy scalar of an array as the Python value a message's field would be."""
    return value.item() if isinstance(value, np.generic) else value


class _FieldComparison:
    """Two decoded messages of one type compared field by field, depth first."""

    def __init__(self, store: Any, ulps: int, header_stamps: bool) -> None:
        self.store = store
        self.ulps = ulps
        self.header_stamps = header_stamps
        self._fields: Dict[str, List[_Field]] = {}

    def fields(self, type_name: str) -> List[_Field]:
        """Return the compared fields of a message type, in the order of its definition."""
        found = self._fields.get(type_name)
        if found is None:
            attributes = [f.name for f in dataclasses.fields(self.store.types[type_name])]
            found = []
            for (name, (kind, details)), attribute in zip(
                    self.store.fielddefs[type_name][1], attributes):
                sequence = kind in (Nodetype.ARRAY, Nodetype.SEQUENCE)
                if sequence:
                    kind, details = details[0]
                message = kind == Nodetype.NAME
                if (name, type_name) != ('stamp', HEADER_TYPE) or self.header_stamps:
                    found.append(_Field(name, attribute, details if message else details[0],
                                        message, sequence))
            self._fields[type_name] = found
        return found

    def messages(self, first: Any, second: Any, type_name: str,
                 path: str = '') -> Optional[_FieldDifference]:
        """Return the first field in which two messages differ (None: they match)."""
        for field in self.fields(type_name):
            where = f'{path}.{field.name}' if path else field.name
            a, b = getattr(first, field.attribute), getattr(second, field.attribute)
            found = (self.sequences(a, b, field, where) if field.sequence
                     else self.messages(a, b, field.type_name, where) if field.message
                     else self.values(a, b, field.type_name, where))
            if found is not None:
                return found
        return None

    def sequences(self, first: Any, second: Any, field: _Field,
                  path: str) -> Optional[_FieldDifference]:
        """Compare an array or sequence field: its length, then element by element."""
        if len(first) != len(second):
            return _FieldDifference(f'len({path})', len(first), len(second), None)
        indexes: Iterable[int] = range(len(first))
        if isinstance(first, np.ndarray) and isinstance(second, np.ndarray):
            if first.tobytes() == second.tobytes():
                return None
            unsigned = np.dtype(f'u{first.dtype.itemsize}')  # compare the bits, NaNs too
            indexes = np.flatnonzero(first.view(unsigned) != second.view(unsigned)).tolist()
        for index in indexes:
            where = f'{path}[{index}]'
            found = (self.messages(first[index], second[index], field.type_name, where)
                     if field.message
                     else self.values(first[index], second[index], field.type_name, where))
            if found is not None:
                return found
        return None

    def values(self, first: Any, second: Any, type_name: str,
               path: str) -> Optional[_FieldDifference]:
        """Compare two values of a base type: floats by bits or ulps, the rest by equality."""
        width = FLOAT_WIDTHS.get(type_name)
        if width is not None:
            a, b = ((np.float32(first), np.float32(second)) if width == 32
                    else (float(first), float(second)))
            if _floats_match(a, b, self.ulps):
                return None
            return _FieldDifference(path, a, b, ulp_distance(a, b))
        if first == second:
            return None
        return _FieldDifference(path, _plain(first), _plain(second), None)


def _run(source: RunSource) -> Run:
    """Return a run to compare: a Run as it is, a path opened (RunFileError if unreadable)."""
    return source if isinstance(source, Run) else open_run(source)


def _compared_topics(first: Run, second: Run,
                     topics: Topics) -> Tuple[List[str], Optional[RunDifference]]:
    """Return the topics to compare, and the first whose type is not the same in both runs."""
    first_types, second_types = first.topics(), second.topics()
    if topics is None:
        wanted = sorted(first_types.keys() | second_types.keys())
    else:
        wanted = sorted({absolute_topic(t) for t in ([topics] if isinstance(topics, str)
                                                     else topics)})
        absent = [t for t in wanted if t not in first_types and t not in second_types]
        if absent:
            raise ValueError(f'{", ".join(absent)}: in neither run (the first has '
                             f'{", ".join(sorted(first_types)) or "no topic"}, the second '
                             f'{", ".join(sorted(second_types)) or "no topic"})')
    for topic in wanted:
        if first_types.get(topic) != second_types.get(topic):
            return wanted, RunDifference(topic, None, None, MESSAGE_TYPE,
                                         first_types.get(topic), second_types.get(topic))
    for run in (first, second):
        for topic in wanted:
            encoding = run.channel(topic).message_encoding
            if encoding != 'cdr':
                raise RunFileError(f'{run.path!r}: {topic} is encoded as {encoding!r}; runs '
                                   'are compared by their CDR messages only')
    return wanted, None


def _recorded_types(run: Run, topic: str, type_name: str) -> Dict[str, Any]:
    """Return the type (and the types it uses) as the run's own definition states it."""
    schema = run.schema(run.channel(topic))
    if schema is None or not schema.data:
        raise RunFileError(f'{run.path!r}: {topic} is of type {type_name or "(none recorded)"}, '
                           'which ROS 2 Jazzy does not define and the run holds no definition of')
    try:
        text = schema.data.decode('utf-8')
        if schema.encoding == 'ros2msg':
            return dict(get_types_from_msg(text, type_name))
        if schema.encoding == 'ros2idl':
            return dict(get_types_from_idl(text))
    except Exception as error:  # rosbags' parser raises several types on malformed text
        raise RunFileError(f'{run.path!r}: the recorded definition of {type_name} is '
                           f'unreadable ({describe_error(error)})') from None
    raise RunFileError(f'{run.path!r}: the definition of {type_name} is in an unknown '
                       f'encoding {schema.encoding!r} (expected ros2msg or ros2idl)')


def _type_store(first: Run, second: Run, topics: List[str]) -> Any:
    """
    Return the type store that decodes the compared topics.

    The package's Jazzy store, unless a topic's type is not a Jazzy type: then a store of the
    comparison's own, with the runs' definitions added (they must agree).
    """
    store = jazzy_typestore()
    types = first.topics()
    unknown = {topic: types[topic] for topic in topics if types[topic] not in store.fielddefs}
    if not unknown:
        return store
    store = get_typestore(Stores.ROS2_JAZZY)
    for topic, type_name in sorted(unknown.items()):
        if type_name in store.fielddefs:
            continue  # a second topic of a type already added
        first_types = _recorded_types(first, topic, type_name)
        second_types = _recorded_types(second, topic, type_name)
        if first_types.get(type_name) != second_types.get(type_name):
            raise RunFileError(f'{first.path!r} and {second.path!r} define {type_name} '
                               'differently; their messages cannot be compared field by field')
        store.register({name: definition
                        for name, definition in {**second_types, **first_types}.items()
                        if name not in store.fielddefs})
    return store


class _Comparison:
    """Two runs streamed side by side and compared message by message."""

    def __init__(self, first: Run, second: Run, topics: List[str], fields: _FieldComparison,
                 log_times: bool) -> None:
        self.first, self.second = first, second
        self.topics = topics
        self.fields = fields
        self.log_times = log_times

    def first_difference(self) -> Optional[RunDifference]:
        """Return the first difference in the first run's log-time order (None: none)."""
        # The second run's messages, topic by topic: each topic's reader holds one chunk.
        partners = {topic: self.second.messages(topic) for topic in self.topics}
        counts = dict.fromkeys(self.topics, 0)
        for message in self.first.messages(self.topics):
            index = counts[message.topic]
            counts[message.topic] += 1
            partner = next(partners[message.topic], None)
            if partner is None:
                total = sum(1 for _ in self.first.messages(message.topic))
                return RunDifference(message.topic, index, message.log_time, MESSAGE_COUNT,
                                     total, index)
            found = self.pair(message, partner, index)
            if found is not None:
                return found
        return self.extra_messages(partners, counts)

    def extra_messages(self, partners: Dict[str, Iterator[MessageTuple]],
                       counts: Dict[str, int]) -> Optional[RunDifference]:
        """Return the earliest message the second run holds beyond the first's (None: none)."""
        extra = [(message.log_time, topic, message) for topic, message in
                 ((topic, next(reader, None)) for topic, reader in partners.items())
                 if message is not None]
        if not extra:
            return None
        log_time, topic, _ = min(extra, key=lambda found: found[:2])
        total = counts[topic] + 1 + sum(1 for _ in partners[topic])
        return RunDifference(topic, counts[topic], log_time, MESSAGE_COUNT, counts[topic],
                             total)

    def pair(self, ours: MessageTuple, theirs: MessageTuple,
             index: int) -> Optional[RunDifference]:
        """Compare the index-th messages of a topic: log time, then every field."""
        if self.log_times and ours.log_time != theirs.log_time:
            return RunDifference(ours.topic, index, ours.log_time, LOG_TIME, ours.log_time,
                                 theirs.log_time)
        if ours.data == theirs.data:
            return None  # the same bytes decode to the same fields
        found = self.fields.messages(self.decoded(self.first, ours, index),
                                     self.decoded(self.second, theirs, index),
                                     ours.schema_name)
        if found is None:
            return None
        return RunDifference(ours.topic, index, ours.log_time, *found)

    def decoded(self, run: Run, message: MessageTuple, index: int) -> Any:
        """
        Decode a message; RunFileError naming it if its bytes are not its type's.

        Bytes after the message's last field are no field, as padding is not: rclpy's
        serialize_message returns the size it estimated (8 bytes more for a ParameterEvent),
        and a run written with it holds them. So the store's decoder is called without the
        store's check that the bytes end with the message.
        """
        try:
            encapsulation = message.data[:2]
            if encapsulation not in CDR_ENCAPSULATIONS:
                raise ValueError(f'the CDR encapsulation is {encapsulation.hex()}, not a plain '
                                 'CDR one (0000 or 0001)')
            store = self.fields.store
            definition = store.get_msgdef(message.schema_name)
            decode = (definition.deserialize_cdr_le if encapsulation[1]
                      else definition.deserialize_cdr_be)
            return decode(memoryview(message.data)[4:], 0, definition.cls, store)[0]
        except Exception as error:  # rosbags raises several types on malformed bytes
            raise RunFileError(f'{run.path!r}: {message.topic} message {index} cannot be '
                               f'decoded as {message.schema_name} '
                               f'({describe_error(error)})') from None


def first_difference(first: RunSource, second: RunSource, ulps: int = 0, *,
                     topics: Topics = None, log_times: bool = True,
                     header_stamps: bool = True) -> Optional[RunDifference]:
    """
    Return where two runs first differ, or None if they match.

    Compared: the topics and their types, then message by message in the first run's
    log-time order (paired by topic and index): the log time, then every decoded field, depth
    first. Floats match bit for bit, or with ulps > 0 within that many units in the last
    place (ulp_distance; a float32 field in float32's). ``topics``: compare only these;
    ``log_times=False``: ignore the log times; ``header_stamps=False``: ignore the stamp of
    every header. A run is a path or a Run; RunFileError (a ValueError) if one is missing,
    not MCAP, damaged or holds a message that does not decode.
    """
    if isinstance(ulps, bool) or not isinstance(ulps, (int, np.integer)) or ulps < 0:
        raise ValueError(f'ulps={ulps!r}: must be a whole number >= 0')
    first_run, second_run = _run(first), _run(second)
    wanted, difference = _compared_topics(first_run, second_run, topics)
    if difference is not None:
        return difference
    fields = _FieldComparison(_type_store(first_run, second_run, wanted), int(ulps),
                              header_stamps)
    return _Comparison(first_run, second_run, wanted, fields, log_times).first_difference()


def assert_runs_match(first: RunSource, second: RunSource, ulps: int = 0, *,
                      topics: Topics = None, log_times: bool = True,
                      header_stamps: bool = True) -> None:
    """Raise AssertionError saying where two runs first differ, if they do (first_difference)."""
    difference = first_difference(first, second, ulps, topics=topics, log_times=log_times,
                                  header_stamps=header_stamps)
    if difference is not None:
        how = 'bit for bit' if ulps == 0 else f'within {ulps} ulps'
        raise AssertionError(f'the runs differ (compared {how}):\n'
                             f'  first:  {_name(first)}\n  second: {_name(second)}\n'
                             f'  {difference}')


def _name(source: RunSource) -> str:
    """Return the path of a run, for a message."""
    return source.path if isinstance(source, Run) else os.fspath(source)
