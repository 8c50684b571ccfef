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
Reader for recorded runs (MCAP files written by ``mcap_recorder`` or rosbag2).

Built on the ``mcap`` library, and never silent about damage. A finished file is read through
its summary, once the summary passes the footer's CRC: chunk by chunk, each checked against its
own CRC, so a damaged chunk costs only its own messages; it is reported to ``on_loss`` as a
:class:`Loss` (its log-time span and, from its message indexes, how many messages of the wanted
topics it held), or raises :class:`RunFileError` for a caller who asked for no report. An
unfinished file (the recorder was killed, the machine lost power, the disk filled up), or one
whose summary is damaged, is streamed from the start up to its last whole record;
``truncated`` and ``problem`` say what happened, as soon as the file is opened.

    run = open_run('runs/qrm_20260101_120000.mcap')
    run.metadata['qrm_ros.geometry']        # {'coupling_radius': '0.025', ...}
    losses = []
    for message in run.messages(['/joint_states'], on_loss=losses.append):
        message.topic, message.log_time, message.data
"""

import heapq
import os
from typing import (BinaryIO, Callable, Dict, Generator, Iterable, Iterator, List, NamedTuple,
                    Optional, Set, Tuple, Union)

from mcap.exceptions import EndOfFile
from mcap.reader import SeekingReader
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, McapRecord, Message,
                          Metadata, Schema)
from mcap.stream_reader import StreamReader
from mcap.summary import Summary

from qrm_ros.recording.mcap_structure import (chunk_records, data_section_matches_crc,
                                              describe_error, indexed_message_count, MAGIC,
                                              read_chunk, read_summary, RunFileError)

__all__ = ['ChannelLabels', 'Loss', 'MessageTuple', 'open_run', 'Run', 'RunFileError', 'Stop',
           'Topics']


class MessageTuple(NamedTuple):
    """One recorded message; a tuple, so ``topic, schema, log, publish, data = m`` still works."""

    topic: str
    schema_name: str
    log_time: int  # ns
    publish_time: int  # ns
    data: bytes


class Loss(NamedTuple):
    """What one damaged part of a file took with it (times: log time in ns)."""

    reason: str
    start_time: Optional[int]  # None: unknown
    end_time: Optional[int]
    messages: Optional[int]  # of the topics asked for; None: unknown


class Stop(NamedTuple):
    """Why a streamed read ended before the footer: the last whole record ends at last_whole."""

    last_whole: int
    size: int
    error: Exception


Topics = Union[str, Iterable[str], None]
# Channel id -> (topic, schema name) of the channels a read wants.
ChannelLabels = Dict[int, Tuple[str, str]]


def _normalise(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic


def _wanted(topics: Topics) -> Optional[Set[str]]:
    if topics is None:
        return None
    return {_normalise(topics)} if isinstance(topics, str) else {_normalise(t) for t in topics}


class Run:
    """One recorded run. Build it with :func:`open_run`."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.metadata: Dict[str, Dict[str, str]] = {}
        self.truncated = False
        self.problem: Optional[str] = None
        self.start_time: Optional[int] = None  # log time of the first message, ns
        self.data_complete = True  # False: the data section could not be read to its end
        self._schemas: Dict[int, Schema] = {}
        self._channels: Dict[int, Channel] = {}
        self._counts: Dict[int, int] = {}
        self._chunk_indexes: List[ChunkIndex] = []  # in file order; empty when streamed
        self._indexed = False
        try:
            with open(path, 'rb') as handle:
                if handle.read(len(MAGIC)) != MAGIC:
                    raise RunFileError(f'{path!r} is not an MCAP file (it does not start with '
                                       'the MCAP magic bytes)')
                summary, summary_problem = read_summary(handle)
                if summary is not None:
                    self._read_index(handle, summary)
                    self._check_data_section(handle)
        except FileNotFoundError:
            raise RunFileError(f'run file {path!r} does not exist') from None
        except IsADirectoryError:
            raise RunFileError(f'{path!r} is a folder, not a run file') from None
        except PermissionError as error:
            raise RunFileError(f'cannot open run file {path!r}: {error.strerror}') from None
        except OSError as error:
            raise RunFileError(f'cannot read run file {path!r}: {error.strerror}') from None
        if not self._indexed:
            self._scan_definitions(summary_problem)

    # --- structure -----------------------------------------------------------------------

    def _check_data_section(self, handle: BinaryIO) -> None:
        if not data_section_matches_crc(handle):
            self.truncated = True
            self.problem = ('its data section fails its CRC: a record outside the chunks '
                            '(metadata such as the geometry, or an index) is damaged, so what '
                            'the metadata says may be wrong; every chunk passed its own CRC')

    def _read_index(self, handle: BinaryIO, summary: Summary) -> None:
        self._schemas = dict(summary.schemas)
        self._channels = dict(summary.channels)
        self._chunk_indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        if summary.statistics is not None:
            self._counts = dict(summary.statistics.channel_message_counts)
            if summary.statistics.message_count:
                self.start_time = summary.statistics.message_start_time
        elif self._chunk_indexes:
            self.start_time = min(c.message_start_time for c in self._chunk_indexes)
        try:
            handle.seek(0)
            reader = SeekingReader(handle, record_size_limit=os.fstat(handle.fileno()).st_size)
            self.metadata = {record.name: dict(record.metadata)
                             for record in reader.iter_metadata()}
        except Exception as error:  # the mcap library's and struct's errors on odd bytes
            raise RunFileError(f'{self.path!r}: damaged metadata record '
                               f'({describe_error(error)})') from None
        self._indexed = True

    def _records(self) -> Generator[McapRecord, None, Optional[Stop]]:
        """Stream the file's records up to the last whole one; return why it stopped early."""
        with open(self.path, 'rb') as handle:
            size = os.fstat(handle.fileno()).st_size
            reader = StreamReader(handle, emit_chunks=True, validate_crcs=True,
                                  record_size_limit=size)
            last_whole = len(MAGIC)
            try:
                for record in reader.records:
                    if isinstance(record, Chunk):
                        inside = chunk_records(record)
                        last_whole = handle.tell()
                        yield from inside
                    else:
                        last_whole = handle.tell()
                        yield record
            except Exception as error:  # the mcap library, zstandard and lz4 raise their own
                return Stop(last_whole, size, error)
        return None

    def _scan_definitions(self, summary_problem: Optional[str]) -> None:
        data_end = footer = False
        records = self._records()
        while True:
            try:
                record = next(records)
            except StopIteration as end:
                stopped = end.value
                break
            if isinstance(record, Message):
                self._counts[record.channel_id] = self._counts.get(record.channel_id, 0) + 1
                if self.start_time is None or record.log_time < self.start_time:
                    self.start_time = record.log_time
            elif isinstance(record, Channel):
                self._channels[record.id] = record
            elif isinstance(record, Schema):
                self._schemas[record.id] = record
            elif isinstance(record, Metadata):
                self.metadata[record.name] = dict(record.metadata)
            elif isinstance(record, DataEnd):
                data_end = True
            elif isinstance(record, Footer):
                footer = True
        self.data_complete = stopped is None or data_end
        if summary_problem:
            self.truncated = True
            self.problem = (f'{summary_problem}: every message was read from the data section'
                            if stopped is None else f'{summary_problem}; '
                            + self._stop_text(stopped))
            return
        if footer and stopped is None:
            return  # finished, just not indexed by chunk
        self.truncated = True
        if data_end:
            self.problem = ('the file ends inside its summary (the recorder was stopped while '
                            'finishing it); every message was read from the data section')
            return
        self.problem = ('the file was not finished (the recorder was killed, lost power or ran '
                        'out of disk): no summary; ' + self._stop_text(stopped)
                        + '. Messages received after the last whole chunk are lost.')

    @staticmethod
    def _stop_text(stopped: Stop) -> str:
        # Without a footer the stream always stops on an error: EndOfFile where the file was
        # cut short, anything else where a record is damaged.
        last_whole, size, error = stopped
        lost = size - last_whole
        return (f'read up to its last whole record at byte {last_whole} of {size}'
                + (f' ({lost} bytes after it are incomplete and ignored)' if lost else '')
                + ('' if isinstance(error, EndOfFile)
                   else f'; the record there is damaged: {describe_error(error)}'))

    # --- public API ----------------------------------------------------------------------

    def topics(self) -> Dict[str, str]:
        """Topic name -> schema name (e.g. 'sensor_msgs/msg/JointState') of every channel."""
        return {channel.topic: self._schema_name(channel) for channel in self._channels.values()}

    def _schema_name(self, channel: Channel) -> str:
        schema = self._schemas.get(channel.schema_id)
        return schema.name if schema is not None else ''

    def channel(self, topic: str) -> Channel:
        """Return the mcap Channel record of a topic (encoding, metadata, schema id)."""
        for channel in self._channels.values():
            if channel.topic == _normalise(topic):
                return channel
        raise KeyError(topic)

    def schema(self, channel: Channel) -> Optional[Schema]:
        """Return the Schema record of a channel (None if it has none)."""
        return self._schemas.get(channel.schema_id)

    def channel_metadata(self, topic: str) -> Dict[str, str]:
        """Return the channel's metadata (offered_qos_profiles, topic_type_hash) of a topic."""
        return dict(self.channel(topic).metadata)

    def schema_text(self, schema_name: str) -> str:
        """Return the message definition stored for a schema name."""
        for schema in self._schemas.values():
            if schema.name == schema_name:
                return schema.data.decode('utf-8', errors='replace')
        raise KeyError(schema_name)

    def parts(self, count: int) -> List[Optional[slice]]:
        """
        Split the file into at most `count` parts of about equal chunk counts.

        Each part (a slice of the chunks in file order; None: the whole file) is a ``part``
        for messages(), e.g. to decode the parts in parallel: every message is in exactly one.
        An unindexed run is one part.
        """
        chunks = len(self._chunk_indexes)
        if not self._indexed or count < 2 or chunks < 2:
            return [None]
        cuts = sorted({chunks * k // count for k in range(count + 1)})
        return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:])]

    def messages(self, topics: Topics = None, log_time_order: bool = True,
                 starting_at: Optional[int] = None, ending_before: Optional[int] = None,
                 part: Optional[slice] = None,
                 on_loss: Optional[Callable[[Loss], None]] = None) -> Iterator[MessageTuple]:
        """
        Yield the messages as :class:`MessageTuple`.

        ``topics``: names to keep ('joint_states' and '/joint_states' both work); None = all.
        ``starting_at`` / ``ending_before``: log-time bounds in ns (None: open).
        ``part``: one of parts() (indexed files).
        Messages come in log-time order, or with log_time_order=False in file order (faster:
        no merge); an unfinished file is always streamed in file order, which the recorder
        writes in log time. A chunk that fails its CRC, decompression or framing is skipped
        and reported to ``on_loss``; without on_loss it raises RunFileError. (Where a streamed
        file stops being readable is known when it is opened: ``truncated``, ``problem``.)
        """
        wanted = _wanted(topics)
        labels: ChannelLabels = {cid: (c.topic, self._schema_name(c))
                                 for cid, c in self._channels.items()
                                 if wanted is None or c.topic in wanted}
        if not labels:
            return
        low = -1 if starting_at is None else starting_at
        high = float('inf') if ending_before is None else ending_before
        if self._indexed:
            yield from self._indexed_messages(labels, log_time_order, low, high, part, on_loss)
            return
        for record in self._records():
            if (isinstance(record, Message) and record.channel_id in labels
                    and low <= record.log_time < high):
                topic, schema = labels[record.channel_id]
                yield MessageTuple(topic, schema, record.log_time, record.publish_time,
                                   record.data)

    def _indexed_messages(self, labels: ChannelLabels, log_time_order: bool, low: float,
                          high: float, part: Optional[slice],
                          on_loss: Optional[Callable[[Loss], None]]) -> Iterator[MessageTuple]:
        chunks = self._chunk_indexes if part is None else self._chunk_indexes[part]
        chunks = [c for c in chunks if c.message_end_time >= low and c.message_start_time < high
                  and (not c.message_index_offsets
                       or any(cid in labels for cid in c.message_index_offsets))]
        if log_time_order:
            chunks.sort(key=lambda c: c.message_start_time)
        # (log time, chunk, position, message): a merge across overlapping chunks
        pending: List[Tuple[int, int, int, MessageTuple]] = []
        with open(self.path, 'rb') as handle:
            for sequence, index in enumerate(chunks):
                try:
                    records = read_chunk(handle, index, labels)
                except Exception as error:  # the mcap library, zstandard and lz4's own errors
                    loss = Loss(f'damaged chunk at byte {index.chunk_start_offset} '
                                f'({describe_error(error)})', index.message_start_time,
                                index.message_end_time,
                                indexed_message_count(handle, index, labels))
                    if on_loss is None:
                        raise RunFileError(f'{self.path!r}: {loss.reason}') from None
                    on_loss(loss)
                    continue
                found = [MessageTuple(*labels[channel_id], log_time, publish_time, data)
                         for channel_id, log_time, publish_time, data in records
                         if low <= log_time < high]
                if not log_time_order:
                    yield from found
                    continue
                while pending and pending[0][0] < index.message_start_time:
                    yield heapq.heappop(pending)[-1]
                for position, message in enumerate(found):
                    heapq.heappush(pending, (message.log_time, sequence, position, message))
        while pending:
            yield heapq.heappop(pending)[-1]

    def message_count(self, topic: Topics = None) -> int:
        """Messages in the file, or on some topics (from the statistics when present)."""
        wanted = _wanted(topic)
        return sum(count for cid, count in self._counts.items()
                   if cid in self._channels
                   and (wanted is None or self._channels[cid].topic in wanted))

    @property
    def counted(self) -> bool:
        """Whether message_count() is the file's own statistics (a finished, sound file)."""
        return self._indexed and bool(self._counts)


def open_run(path: Union[str, 'os.PathLike[str]']) -> Run:
    """Open a recorded run; raises RunFileError if the file is missing or not MCAP."""
    return Run(os.fspath(path))
