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
The MCAP file of one run, written as rosbag2's MCAP storage plugin writes it; no ROS in here.

Chunks are closed (and fsynced) whenever ``max_chunk_duration`` of log time has passed, so
SIGKILL or power loss costs at most that much (plus one fsync: fsync runs on a thread of its
own, so a slow disk never stalls the caller's message intake);
``qrm_ros.recording.bag_reader`` reads such an unfinished file up to its last whole chunk and
``mcap_recorder --recover`` finishes it. A write that fails cuts the file back to its last
whole chunk; one that fails before anything was written leaves no file at all.
"""

from concurrent.futures import Future, ThreadPoolExecutor
import errno
import os
from typing import (Any, Callable, Dict, Optional, Sequence, Tuple, TYPE_CHECKING, TypeVar,
                    Union)

from mcap.writer import CompressionType, Writer

from qrm_ros.recording.rosbag2_formats import (find_message_definition, offered_qos_profiles_yaml,
                                               rosbag2_metadata_yaml)

if TYPE_CHECKING:  # the recorder hands over rclpy's profiles; this module never imports ROS
    from rclpy.qos import QoSProfile

__all__ = ['COMPRESSIONS', 'CHUNK_SIZE_BYTES', 'ConfigurationError', 'McapRunFile',
           'RecorderError', 'WriteFailed']

COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}
# Closing a chunk early by size keeps memory bounded at high rates; duration is the usual limit.
CHUNK_SIZE_BYTES = 4 * 1024 * 1024
LIBRARY = 'qrm_ros mcap_recorder'
NO_ROOM = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
# A channel's (topic, type name, offered_qos_profiles YAML, type hash).
ChannelInfo = Tuple[str, str, str, str]
Result = TypeVar('Result')


class RecorderError(Exception):
    """A condition that ends the recording with a one-line message and a non-zero exit."""


class ConfigurationError(RecorderError):
    """The user asked for something refused before anything is recorded (exit code 2)."""


class WriteFailed(RecorderError):
    """
    A write to the run file failed: the file ends on its last complete chunk.

    Said for the recorder (whose file stays, to recover); path, reason and no_room (the disk
    or the size limit is full) let a command that removes its file say it its own way.
    """

    def __init__(self, text: str, path: str, reason: str, no_room: bool) -> None:
        super().__init__(text)
        self.path, self.reason, self.no_room = path, reason, no_room


class McapRunFile:
    """The MCAP writer plus the chunk, fsync and error bookkeeping."""

    def __init__(self, path: str, compression: CompressionType,
                 max_chunk_duration_ns: int) -> None:
        folder = os.path.dirname(os.path.abspath(path))
        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as error:
            raise RecorderError(f'cannot create output {path!r}: folder {folder!r}: '
                                f'{error.strerror} (errno {error.errno})') from None
        try:
            self._stream = open(path, 'xb', buffering=1024 * 1024)
        except FileExistsError:
            raise ConfigurationError(f'output {path!r} already exists; refusing to overwrite '
                                     'it (choose another output path)') from None
        except OSError as error:
            raise RecorderError(f'cannot create output {path!r}: {error.strerror} '
                                f'(errno {error.errno})') from None
        self.path = path
        self._max_chunk_duration_ns = max_chunk_duration_ns
        # Data-section CRC: the reader then also checks the metadata records.
        self._writer = Writer(self._stream, chunk_size=1 << 62, compression=compression,
                              enable_data_crcs=True)
        self._schemas: Dict[str, Tuple[int, Optional[str]]] = {}  # type -> (id, problem)
        self._counts: Dict[int, int] = {}
        self._channel_info: Dict[int, ChannelInfo] = {}
        self._chunk_start_ns: Optional[int] = None
        self._chunk_bytes = 0
        self._good_offset = 0
        self.message_count = 0
        self.message_count_on_disk = 0
        self._syncer = ThreadPoolExecutor(max_workers=1, thread_name_prefix='mcap_fsync')
        # the fsync in flight: a future of (offset, message count)
        self._sync: Optional[Future[Tuple[int, int]]] = None
        self.start_ns: Optional[int] = None
        self.end_ns: Optional[int] = None
        self.failed = False
        try:
            self._writer.start('ros2', LIBRARY)
            self._commit(wait=True)
        except OSError as error:
            # Nothing worth keeping was written: an empty file would only mislead.
            self._abandon()
            try:
                os.unlink(path)
            except OSError:
                pass
            raise RecorderError(f'cannot write {path!r}: {error.strerror or error} (errno '
                                f'{error.errno}); no file was left behind'
                                + self._what_to_do(error)) from None

    @staticmethod
    def _what_to_do(error: Exception) -> str:
        if isinstance(error, OSError) and error.errno in NO_ROOM:
            return ('; free space on that disk (or raise the file size limit) or choose '
                    'another output (-p output:=PATH)')
        return ''

    def _guard(self, operation: Callable[..., Result], *args: Any) -> Result:
        try:
            return operation(*args)
        except OSError as error:
            raise self._write_failed(error) from None

    def _write_failed(self, error: OSError) -> RecorderError:
        """Let go of the file after a failed write; return the error that says so."""
        self._abandon()
        reason = f'{error.strerror or error} (errno {error.errno})'
        return WriteFailed(
            f'cannot write {self.path!r}: {reason}; the file keeps the '
            f'{self.message_count_on_disk} messages up to its last complete chunk (finish it '
            'with mcap_recorder --recover)' + self._what_to_do(error),
            self.path, reason, error.errno in NO_ROOM)

    def _commit(self, wait: bool = False) -> None:
        # Everything buffered goes to the OS now; to the disk by an fsync on the sync thread.
        self._writer.flush()
        self._chunk_start_ns = None
        self._chunk_bytes = 0
        self._collect_sync(wait=wait)  # when waiting, for the one in flight first
        if self._sync is None:  # else the next commit syncs this too
            fd, offset, count = self._stream.fileno(), self._stream.tell(), self.message_count

            def sync_to_disk() -> Tuple[int, int]:
                os.fsync(fd)
                return offset, count
            self._sync = self._syncer.submit(sync_to_disk)
        if wait:
            self._collect_sync(wait=True)

    def _collect_sync(self, wait: bool) -> None:
        """Take the result of a finished fsync (raising its OSError), or wait for it."""
        if self._sync is None or not (wait or self._sync.done()):
            return
        sync, self._sync = self._sync, None
        self._good_offset, self.message_count_on_disk = sync.result()

    def _abandon(self) -> None:
        # Cut any half-written record so the file ends on a whole record, then let go of it.
        self.failed = True
        try:
            self._collect_sync(wait=True)
        except OSError:
            pass
        self._syncer.shutdown()
        fd = self._stream.fileno()
        try:
            os.ftruncate(fd, self._good_offset)
        except OSError:
            pass
        try:
            os.close(fd)
        except OSError:
            pass
        try:
            self._stream.close()
        except (OSError, ValueError):
            pass

    def add_schema(self, type_name: str, definition: Optional[str] = None) -> Optional[str]:
        """
        Register the ``ros2msg`` schema of a type once; return None or why it has no text.

        Without a definition it is built from the ament index; a type whose text cannot be
        built is recorded without a schema (schema id 0), as rosbag2 does.
        """
        if type_name in self._schemas:
            return self._schemas[type_name][1]
        problem = None
        if definition is None:
            definition, problem = find_message_definition(type_name)
        schema_id = 0
        if definition is not None:
            schema_id = self._guard(self._writer.register_schema, type_name, 'ros2msg',
                                    definition.encode('utf-8'))
        self._schemas[type_name] = (schema_id, problem)
        return problem

    def add_channel(self, topic: str, type_name: str,
                    offered_qos: Union[str, Sequence['QoSProfile']], type_hash: str) -> int:
        """
        Register a topic; return its channel id.

        ``offered_qos`` is the publishers' QoS profiles, or their YAML text as found in a
        channel's ``offered_qos_profiles`` metadata.
        """
        self.add_schema(type_name)
        qos_yaml = (offered_qos if isinstance(offered_qos, str)
                    else offered_qos_profiles_yaml(offered_qos))
        metadata = {'offered_qos_profiles': qos_yaml, 'topic_type_hash': type_hash}
        channel_id = self._guard(self._writer.register_channel, topic, 'cdr',
                                 self._schemas[type_name][0], metadata)
        self._counts[channel_id] = 0
        self._channel_info[channel_id] = (topic, type_name, qos_yaml, type_hash)
        return channel_id

    def add_message(self, channel_id: int, log_time_ns: int, publish_time_ns: int,
                    data: bytes) -> None:
        # _guard's work written out (once per message, its call cost counts).
        try:
            chunk_start_ns = self._chunk_start_ns
            if chunk_start_ns is None:
                self._chunk_start_ns = log_time_ns
            elif log_time_ns - chunk_start_ns >= self._max_chunk_duration_ns:
                self._commit()
                self._chunk_start_ns = log_time_ns
            self._writer.add_message(channel_id, log_time_ns, data, publish_time_ns)
            self._counts[channel_id] += 1
            self.message_count += 1
            if self.start_ns is None or log_time_ns < self.start_ns:
                self.start_ns = log_time_ns
            if self.end_ns is None or log_time_ns > self.end_ns:
                self.end_ns = log_time_ns
            self._chunk_bytes += len(data)
            if self._chunk_bytes >= CHUNK_SIZE_BYTES:
                self._commit()
        except OSError as error:
            raise self._write_failed(error) from None

    def close_chunk_if_due(self, now_ns: int) -> None:
        if (self._chunk_start_ns is not None
                and now_ns - self._chunk_start_ns >= self._max_chunk_duration_ns):
            self._guard(self._commit)

    def add_metadata(self, name: str, data: Dict[str, str]) -> None:
        self._guard(self._writer.add_metadata, name, data)

    def add_attachment(self, create_time_ns: int, log_time_ns: int, name: str, media_type: str,
                       data: bytes) -> None:
        self._guard(self._writer.add_attachment, create_time_ns, log_time_ns, name,
                    media_type, data)

    def finish(self) -> None:
        topics = [info + (self._counts[cid],) for cid, info in self._channel_info.items()]
        yaml_text = rosbag2_metadata_yaml(self.path, topics, self.start_ns or 0,
                                          self.end_ns or 0)
        self._guard(self._writer.add_metadata, 'rosbag2', {'serialized_metadata': yaml_text})
        self._guard(self._writer.finish)
        self._guard(self._commit, True)
        self._syncer.shutdown()
        self._stream.close()

    def topic_counts(self) -> Dict[str, int]:
        return {info[0]: self._counts[cid] for cid, info in self._channel_info.items()}
