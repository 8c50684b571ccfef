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
Finish a recording left unfinished (SIGKILL, power loss, full disk), like ``mcap recover``.

Everything readable in the broken file (schemas, channels, messages, metadata, attachments of
every whole chunk whose CRC and compression check out) is rewritten through the recorder's own
writer into a new file with chunk indexes, a summary, statistics and a fresh ``rosbag2``
record, so ``rosbags``, ``ros2 bag`` and Foxglove open it. What could not be read is said, in
messages and log-time spans where the file still tells them; nothing is dropped silently.
"""

import dataclasses
import os
import struct
import sys
from typing import BinaryIO, Callable, Dict, Iterator, List, NoReturn, Optional, Tuple, TextIO

from mcap.exceptions import McapError
from mcap.records import (Attachment, Channel, Chunk, DataEnd, Footer, Header, McapRecord,
                          Message, Metadata, Schema)
from mcap.stream_reader import breakup_chunk, StreamReader

from qrm_ros.recording.mcap_run_file import (COMPRESSIONS, ConfigurationError, McapRunFile,
                                             RecorderError)

__all__ = ['RECOVERY_METADATA', 'recover', 'recover_command', 'recovered_losses', 'Recovery']

ROSBAG2_METADATA = 'rosbag2'  # rebuilt from what was recovered, never copied
# The losses a recovery said, kept in the file it writes (loss_1, loss_2, ... -> the line),
# so whoever reads the recovered file hears of them again; a second recovery adds its own.
RECOVERY_METADATA = 'qrm_ros.recovery'
# What a damaged or cut-off file makes the mcap library raise (zstd/lz4 raise their own).
_DAMAGE = (McapError, struct.error, ValueError, EOFError, RuntimeError, MemoryError,
           OverflowError)  # a length too large to allocate
_CHUNK_DURATION_NS = 1_000_000_000


@dataclasses.dataclass
class Recovery:
    """What a recovery kept and what it lost."""

    messages: int = 0
    topic_counts: Dict[str, int] = dataclasses.field(default_factory=dict)
    # (start ns, end ns, reason)
    lost_chunks: List[Tuple[int, int, str]] = dataclasses.field(default_factory=list)
    lost_messages: int = 0  # of channels without a readable schema or channel record
    end_problem: str = ''  # why reading stopped before the summary ('' = the data was whole)
    read_bytes: int = 0
    size: int = 0

    def warnings(self) -> List[str]:
        lines = [f'lost a damaged chunk holding log time {start} to {end} ns: {reason}'
                 for start, end, reason in self.lost_chunks]
        if self.lost_messages:
            lines.append(f'lost {self.lost_messages} messages of channels without a readable '
                         'schema or channel record (in a damaged chunk, or none written)')
        if self.end_problem:
            lines.append(f'the last {self.size - self.read_bytes} of {self.size} bytes are '
                         f'not readable ({self.end_problem}): what they held is lost')
        return lines


class _Rewriter:
    """Maps the broken file's schemas and channels onto the new file's."""

    def __init__(self, run_file: McapRunFile, recovery: Recovery) -> None:
        self.run_file = run_file
        self.recovery = recovery
        self.schemas: Dict[int, Schema] = {}
        self.channels: Dict[int, Tuple[int, str]] = {}  # old id -> (new id, topic)
        self.earlier_losses: List[str] = []  # said by an earlier recovery of the same run

    def take(self, record: McapRecord) -> None:
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self._add_channel(record)
        elif isinstance(record, Message):
            channel = self.channels.get(record.channel_id)
            if channel is None:
                self.recovery.lost_messages += 1
                return
            self.run_file.add_message(channel[0], record.log_time, record.publish_time,
                                      record.data)
            self.recovery.messages += 1
            counts = self.recovery.topic_counts
            counts[channel[1]] = counts.get(channel[1], 0) + 1
        elif isinstance(record, Metadata) and record.name == RECOVERY_METADATA:
            self.earlier_losses += recovered_losses({record.name: dict(record.metadata)})
        elif isinstance(record, Metadata) and record.name != ROSBAG2_METADATA:
            self.run_file.add_metadata(record.name, dict(record.metadata))
        elif isinstance(record, Attachment):
            self.run_file.add_attachment(record.create_time, record.log_time, record.name,
                                         record.media_type, record.data)

    def _add_channel(self, channel: Channel) -> None:
        if channel.id in self.channels:
            return
        schema = self.schemas.get(channel.schema_id)
        if schema is None:
            return  # its schema was lost: its messages are counted as lost
        self.run_file.add_schema(schema.name, schema.data.decode('utf-8', 'replace'))
        metadata = channel.metadata
        new_id = self.run_file.add_channel(channel.topic, schema.name,
                                           metadata.get('offered_qos_profiles', '[]'),
                                           metadata.get('topic_type_hash', ''))
        self.channels[channel.id] = (new_id, channel.topic)


def recover(broken: str, fixed: str, compression: str = 'zstd') -> Recovery:
    """Rewrite what is readable in `broken` into the new file `fixed`; return a Recovery."""
    recovery = Recovery(size=os.path.getsize(broken))
    with open(broken, 'rb') as handle:
        reader = StreamReader(handle, emit_chunks=True, record_size_limit=recovery.size)
        records = reader.records
        try:
            first = next(records)
        except Exception:  # noqa: B902 - whatever the reader makes of non-MCAP bytes
            handle.seek(0)
            raise ConfigurationError(
                f'{broken!r} is not an MCAP file (it starts with {handle.read(8)!r}, not the '
                'MCAP magic bytes and header); nothing to recover') from None
        if not isinstance(first, Header):
            raise ConfigurationError(f'{broken!r} does not start with an MCAP header; nothing '
                                     'to recover')
        run_file = McapRunFile(fixed, COMPRESSIONS[compression], _CHUNK_DURATION_NS)
        try:
            rewriter = _Rewriter(run_file, recovery)
            _rewrite(records, handle, rewriter)
            lines = rewriter.earlier_losses + recovery.warnings()
            if lines:
                run_file.add_metadata(RECOVERY_METADATA, {f'loss_{index}': line for index, line
                                                          in enumerate(lines, start=1)})
            run_file.finish()
        except BaseException:
            os.unlink(fixed)  # all or nothing: a half-written recovery would only mislead
            raise
    return recovery


def recovered_losses(metadata: Dict[str, Dict[str, str]]) -> List[str]:
    """Return the losses a recovery kept in a file's metadata (RECOVERY_METADATA), in order."""
    kept = metadata.get(RECOVERY_METADATA, {})

    def number(key: str) -> int:
        digits = key.rpartition('_')[2]
        return int(digits) if digits.isdigit() else 0
    return [kept[key] for key in sorted(kept, key=number)]


def _rewrite(records: Iterator[McapRecord], handle: BinaryIO, rewriter: _Rewriter) -> None:
    recovery = rewriter.recovery
    recovery.read_bytes = handle.tell()
    try:
        for record in records:
            if isinstance(record, (DataEnd, Footer)):
                return  # the summary that follows is rebuilt, not copied
            if isinstance(record, Chunk):
                _take_chunk(record, rewriter)
            else:
                rewriter.take(record)
            recovery.read_bytes = handle.tell()
    except _DAMAGE as error:
        if recovery.read_bytes < recovery.size:  # else it just ends after a whole record
            recovery.end_problem = (f'{type(error).__name__}: {error}' if str(error)
                                    else 'the file ends inside a record')


def _take_chunk(chunk: Chunk, rewriter: _Rewriter) -> None:
    try:
        inner = list(breakup_chunk(chunk, validate_crc=True))
    except Exception as error:  # noqa: B902 - the mcap library, zstandard and lz4's own errors
        rewriter.recovery.lost_chunks.append((chunk.message_start_time,
                                              chunk.message_end_time,
                                              str(error) or type(error).__name__))
        return
    for record in inner:
        rewriter.take(record)


def recover_command(broken: str, fixed: str, usage_error: Callable[[str], NoReturn],
                    out: Optional[TextIO] = None, err: Optional[TextIO] = None) -> int:
    """
    ``mcap_recorder --recover``: 0 done (losses said), 1 nothing readable, 2 bad usage.

    out, err: where it says so (None: this process's standard output and error, as they are
    when it is called, not when this module was imported).
    """
    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    if not os.path.isfile(broken):
        usage_error(f'--recover: {broken!r} does not exist or is not a file')
    if os.path.exists(fixed) or os.path.abspath(fixed) == os.path.abspath(broken):
        usage_error(f'--recover: {fixed!r} already exists; name a new file to write')
    prefix = 'mcap_recorder'
    try:
        recovery = recover(broken, fixed)
    except ConfigurationError as error:
        usage_error(f'--recover: {error}')
    except RecorderError as error:
        print(f'{prefix}: error: {error}', file=err, flush=True)
        return 1
    for line in recovery.warnings():
        print(f'{prefix}: warning: {line}', file=err, flush=True)
    topics = ', '.join(f'{t} {n}' for t, n in sorted(recovery.topic_counts.items()))
    print(f'{prefix}: recovered {recovery.messages} messages into {fixed}'
          + (f': {topics}' if topics else ''), file=out, flush=True)
    return 0
