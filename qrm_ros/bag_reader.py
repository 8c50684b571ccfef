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

Built on the ``mcap`` library. A finished file is read through its summary (chunk indexes,
statistics, metadata index). An unfinished one (the recorder was killed, the machine lost
power, the disk filled up) has no usable summary: it is streamed from the start and read up
to its last whole record, so every complete chunk counts and a partly written one does not;
``truncated`` and ``problem`` say what happened.

    run = open_run('runs/qrm_20260101_120000.mcap')
    run.metadata['qrm_ros.geometry']        # {'coupling_radius': '0.025', ...}
    for topic, schema, log_ns, publish_ns, data in run.messages(['/joint_states']):
        ...
"""

import os
import struct

from mcap.exceptions import EndOfFile, McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

MAGIC = b'\x89MCAP0\r\n'
# What a damaged or cut-off file makes the mcap library raise (zstd/lz4 raise their own).
_DAMAGE = (McapError, struct.error, ValueError, EOFError, RuntimeError)


class RunFileError(ValueError):
    """A run file that cannot be read at all (missing, not MCAP, damaged)."""


def _normalise(topic):
    return topic if topic.startswith('/') else '/' + topic


def _wanted(topics):
    if topics is None:
        return None
    return {_normalise(topics)} if isinstance(topics, str) else {_normalise(t) for t in topics}


class Run:
    """One recorded run. Build it with :func:`open_run`."""

    def __init__(self, path):
        self.path = path
        self.metadata = {}
        self.truncated = False
        self.problem = None
        self._schemas = {}
        self._channels = {}
        self._counts = {}
        try:
            with open(path, 'rb') as handle:
                if handle.read(len(MAGIC)) != MAGIC:
                    raise RunFileError(f'{path!r} is not an MCAP file (it does not start with '
                                       'the MCAP magic bytes)')
                summary = self._summary(handle)
                if summary is not None:
                    self._read_index(handle, summary)
                    return
        except FileNotFoundError:
            raise RunFileError(f'run file {path!r} does not exist') from None
        except IsADirectoryError:
            raise RunFileError(f'{path!r} is a folder, not a run file') from None
        except PermissionError as error:
            raise RunFileError(f'cannot open run file {path!r}: {error.strerror}') from None
        self._scan_definitions()

    # --- structure -----------------------------------------------------------------------

    @staticmethod
    def _summary(handle):
        """Return the summary if the file is finished and indexed by chunk, else None."""
        try:
            handle.seek(0)
            summary = SeekingReader(handle).get_summary()
        except (*_DAMAGE, OSError):  # OSError: too short to seek to a footer
            return None  # no footer: the file was not finished
        if summary is None or (not summary.chunk_indexes and summary.statistics
                               and summary.statistics.message_count):
            return None  # finished but unindexed: stream it
        return summary

    def _read_index(self, handle, summary):
        handle.seek(0)
        reader = SeekingReader(handle)
        self._schemas = dict(summary.schemas)
        self._channels = dict(summary.channels)
        self._chunk_start_times = sorted(c.message_start_time for c in summary.chunk_indexes)
        if summary.statistics is not None:
            self._counts = dict(summary.statistics.channel_message_counts)
        try:
            self.metadata = {record.name: dict(record.metadata)
                             for record in reader.iter_metadata()}
        except _DAMAGE as error:
            raise RunFileError(f'{self.path!r}: damaged metadata record ({error})') from None
        self._indexed = True

    def _records(self):
        """Stream the file's records up to the last whole one; note why it stopped."""
        with open(self.path, 'rb') as handle:
            reader = StreamReader(handle, validate_crcs=True)
            last_whole = len(MAGIC)
            try:
                for record in reader.records:
                    last_whole = handle.tell()
                    yield record
            except Exception as error:  # _DAMAGE, and zstandard / lz4's own error types
                self._stopped = (last_whole, os.fstat(handle.fileno()).st_size, error)

    def _scan_definitions(self):
        self._indexed = False
        self._stopped = None
        data_end = footer = False
        for record in self._records():
            if isinstance(record, Message):
                self._counts[record.channel_id] = self._counts.get(record.channel_id, 0) + 1
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
        if footer and self._stopped is None:
            return  # finished, just not indexed by chunk
        self.truncated = True
        if data_end:
            self.problem = ('the file ends inside its summary (the recorder was stopped while '
                            'finishing it); every message was read from the data section')
            return
        # Without a footer the stream always stops on an error: EndOfFile where the file was
        # cut short, anything else where a record is damaged.
        last_whole, size, error = self._stopped
        damaged = not isinstance(error, EndOfFile)
        lost = size - last_whole
        self.problem = (
            'the file was not finished (the recorder was killed, lost power or ran out of '
            f'disk): no summary; read up to its last whole record at byte {last_whole} of {size}'
            + (f' ({lost} bytes after it are incomplete and ignored)' if lost else '')
            + (f'; the record there is damaged: {error}' if damaged else '')
            + '. Messages received after the last whole chunk are lost.')

    # --- public API ----------------------------------------------------------------------

    def topics(self):
        """Topic name -> schema name (e.g. 'sensor_msgs/msg/JointState') of every channel."""
        return {channel.topic: self._schema_name(channel) for channel in self._channels.values()}

    def _schema_name(self, channel):
        schema = self._schemas.get(channel.schema_id)
        return schema.name if schema is not None else ''

    def channel_metadata(self, topic):
        """Return the channel's metadata (offered_qos_profiles, topic_type_hash) of a topic."""
        for channel in self._channels.values():
            if channel.topic == _normalise(topic):
                return dict(channel.metadata)
        raise KeyError(topic)

    def schema_text(self, schema_name):
        """Return the message definition stored for a schema name."""
        for schema in self._schemas.values():
            if schema.name == schema_name:
                return schema.data.decode('utf-8')
        raise KeyError(schema_name)

    def time_spans(self, count):
        """
        Split the run's log time into at most `count` spans holding about equal chunk counts.

        Returns [(starting_at, ending_before), ...] in ns, None for an open end: the bounds
        for messages(), e.g. to decode the spans in parallel. An unindexed run is one span.
        """
        starts = self._chunk_start_times if self._indexed else []
        cuts = sorted({starts[len(starts) * k // count] for k in range(1, count)} - {starts[0]}
                      ) if count > 1 and len(starts) > 1 else []
        bounds = [None] + cuts + [None]
        return list(zip(bounds[:-1], bounds[1:]))

    def messages(self, topics=None, log_time_order=True, starting_at=None, ending_before=None):
        """
        Yield (topic, schema_name, log_time_ns, publish_time_ns, data).

        ``topics``: names to keep ('joint_states' and '/joint_states' both work); None = all.
        ``starting_at`` / ``ending_before``: log-time bounds in ns (None: open).
        Messages come in log-time order through the chunk index, or with log_time_order=False
        in file order, streamed (faster: no index, no merge); an unfinished file is always
        streamed in file order, which the recorder writes in log time.
        """
        wanted = _wanted(topics)
        labels = {cid: (c.topic, self._schema_name(c)) for cid, c in self._channels.items()
                  if wanted is None or c.topic in wanted}
        if not labels:
            return
        bounded = starting_at is not None or ending_before is not None
        if self._indexed and (log_time_order or bounded):
            with open(self.path, 'rb') as handle:
                reader = SeekingReader(handle)
                try:
                    for _, channel, message in reader.iter_messages(
                            topics=sorted({topic for topic, _ in labels.values()}),
                            starting_at=starting_at, ending_before=ending_before,
                            log_time_order=log_time_order):
                        topic, schema = labels[channel.id]
                        yield topic, schema, message.log_time, message.publish_time, \
                            message.data
                except _DAMAGE as error:
                    raise RunFileError(f'{self.path!r}: damaged chunk ({error})') from None
            return
        low = -1 if starting_at is None else starting_at
        high = float('inf') if ending_before is None else ending_before
        for record in self._records():
            if (isinstance(record, Message) and record.channel_id in labels
                    and low <= record.log_time < high):
                topic, schema = labels[record.channel_id]
                yield topic, schema, record.log_time, record.publish_time, record.data

    def message_count(self, topic=None):
        """Messages in the file, or on one topic (from the statistics when present)."""
        wanted = _wanted(topic)
        return sum(count for cid, count in self._counts.items()
                   if cid in self._channels
                   and (wanted is None or self._channels[cid].topic in wanted))


def open_run(path):
    """Open a recorded run; raises RunFileError if the file is missing or not MCAP."""
    return Run(os.fspath(path))
