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
An MCAP file's parts, read and checked: footer, summary, data section, chunks.

The summary is trusted only once it passes the footer's CRC, the data section its DataEnd
CRC, and each chunk its own CRC and a sane size; a chunk is found through its index entry and
its messages counted from its message indexes.

``qrm_ros.recording.bag_reader`` builds a run's reading on these; they raise
:class:`RunFileError` (or the mcap library's, zstandard's and lz4's own errors) on damage.
"""

import io
import os
import struct
from typing import BinaryIO, Container, List, Optional, Tuple
import zlib

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile
from mcap.opcode import Opcode
from mcap.reader import FOOTER_SIZE, SeekingReader
from mcap.records import Chunk, ChunkIndex, Footer, McapRecord, Message
from mcap.stream_reader import breakup_chunk, get_chunk_data_stream, StreamReader
from mcap.summary import Summary

__all__ = ['chunk_messages', 'chunk_records', 'data_section_matches_crc', 'describe_error',
           'indexed_message_count', 'MAGIC', 'MAX_CHUNK_BYTES', 'RawMessage', 'read_chunk',
           'read_summary', 'RunFileError']

MAGIC = b'\x89MCAP0\r\n'
# A chunk claiming more than this uncompressed is damaged (the recorder's hold about 1 s).
MAX_CHUNK_BYTES = 1 << 30
_RECORD_PREFIX = 1 + 8  # opcode, length
_FOOTER_CRC_END = _RECORD_PREFIX + 8 + 8  # the summary CRC covers the footer up to here
_MESSAGE_INDEX_ENTRY = 16  # log time, offset
_DATA_END_SIZE = _RECORD_PREFIX + 4  # opcode, length, data section CRC
_RECORD_HEAD = struct.Struct('<BQ')  # opcode, length
_MESSAGE_HEAD = struct.Struct('<HIQQ')  # channel id, sequence, log time, publish time
# One message as a chunk holds it: (channel id, log time ns, publish time ns, data).
RawMessage = Tuple[int, int, int, bytes]


class RunFileError(ValueError):
    """A run file that cannot be read at all (missing, not MCAP, damaged)."""


def _check_size(chunk: Chunk) -> None:
    """Refuse a chunk whose claimed size would make decompression allocate absurdly."""
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise RunFileError(f'the chunk claims {chunk.uncompressed_size} bytes uncompressed')


def chunk_records(chunk: Chunk) -> List[McapRecord]:
    """Return a chunk's records once its size and CRC check out; raise on damage."""
    _check_size(chunk)
    return breakup_chunk(chunk, validate_crc=True)


def chunk_messages(chunk: Chunk, channels: Container[int]) -> List[RawMessage]:
    """
    Return (channel id, log time, publish time, data) of the chunk's messages on `channels`.

    The chunk is decompressed and CRC-checked by the mcap library; the records are then
    walked here with one struct call per record instead of the library's per-field reads
    (breakup_chunk), which took 40 % of a long analysis. Anything this walk does not expect
    is handed to the library's own breakup_chunk, so the library stays the judge.
    """
    _check_size(chunk)
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    data = stream.read(size)
    found = []
    position, record_head, message_head = 0, _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    try:
        while position < size:
            opcode, length = record_head(data, position)
            body, position = position + _RECORD_PREFIX, position + _RECORD_PREFIX + length
            if opcode == Opcode.MESSAGE:
                if length < _MESSAGE_HEAD.size:
                    raise ValueError('a message record shorter than its fields')
                channel_id, _, log_time, publish_time = message_head(data, body)
                if channel_id in channels:
                    found.append((channel_id, log_time, publish_time,
                                  data[body + _MESSAGE_HEAD.size:position]))
        if position != size:
            raise ValueError('records overrun the chunk')
    except (struct.error, ValueError):
        return [(r.channel_id, r.log_time, r.publish_time, r.data) for r in chunk_records(chunk)
                if isinstance(r, Message) and r.channel_id in channels]
    return found


def describe_error(error: Exception) -> str:
    """Return the error's type and the first line of its message, for a one-line report."""
    text = str(error).strip().splitlines()
    return f'{type(error).__name__}: {text[0]}' if text else type(error).__name__


def read_summary(handle: BinaryIO) -> Tuple[Optional[Summary], Optional[str]]:
    """
    Return (summary, None) for a finished file indexed by chunk, else (None, why not).

    Why not is None for a file that is simply unfinished or unindexed (it is streamed
    then), or says how its summary is damaged.
    """
    size = os.fstat(handle.fileno()).st_size
    footer_at = size - FOOTER_SIZE - len(MAGIC)
    if footer_at < len(MAGIC):
        return None, None
    handle.seek(footer_at)
    tail = handle.read()
    if tail[0] != Opcode.FOOTER or tail[-len(MAGIC):] != MAGIC:
        return None, None  # no footer: the file was not finished
    try:
        footer = next(StreamReader(io.BytesIO(tail), skip_magic=True).records)
    except Exception as error:  # the mcap library's and struct's errors on odd bytes
        return None, f'its footer is damaged ({describe_error(error)})'
    if not isinstance(footer, Footer) or footer.summary_start == 0:
        return None, None  # finished without a summary: stream it
    if not len(MAGIC) <= footer.summary_start < footer_at:
        return None, f'its footer points outside the file (summary at {footer.summary_start})'
    if footer.summary_crc:
        handle.seek(footer.summary_start)
        covered = handle.read(footer_at + _FOOTER_CRC_END - footer.summary_start)
        if zlib.crc32(covered) != footer.summary_crc:
            return None, 'its summary section fails its CRC'
    try:
        handle.seek(0)
        summary = SeekingReader(handle, record_size_limit=size).get_summary()
    except Exception as error:  # as above
        return None, f'its summary section is unreadable ({describe_error(error)})'
    if summary is None or (not summary.chunk_indexes and summary.statistics
                           and summary.statistics.message_count):
        return None, None  # finished but unindexed: stream it
    return summary, None


def data_section_matches_crc(handle: BinaryIO) -> bool:
    """
    Check the data section against the CRC in its DataEnd record (True: no CRC to check).

    Chunks carry their own CRCs; this is the only one covering the records between them
    (metadata such as the geometry, message indexes). Reading 40 MB costs about 30 ms.
    """
    footer = handle.seek(-(FOOTER_SIZE + len(MAGIC)), io.SEEK_END)
    summary_start = struct.unpack_from('<Q', handle.read(FOOTER_SIZE), _RECORD_PREFIX)[0]
    data_end = (summary_start or footer) - _DATA_END_SIZE
    handle.seek(data_end)
    opcode, length, expected = struct.unpack('<BQI', handle.read(_DATA_END_SIZE))
    if opcode != Opcode.DATA_END or length != 4 or expected == 0:
        return True
    handle.seek(0)
    crc = 0
    for block in iter(lambda: handle.read(min(1 << 20, data_end - handle.tell())), b''):
        crc = zlib.crc32(block, crc)
    return crc == expected


def read_chunk(handle: BinaryIO, index: ChunkIndex,
               channels: Container[int]) -> List[RawMessage]:
    """Read one chunk at its index entry; its messages on `channels`, once it checks out."""
    handle.seek(index.chunk_start_offset)
    prefix = handle.read(_RECORD_PREFIX)
    if len(prefix) < _RECORD_PREFIX:
        raise EndOfFile()
    opcode, length = struct.unpack('<BQ', prefix)
    if opcode != Opcode.CHUNK or _RECORD_PREFIX + length != index.chunk_length:
        raise RunFileError('its record does not match the chunk index')
    return chunk_messages(Chunk.read(ReadDataStream(handle)), channels)


def indexed_message_count(handle: BinaryIO, index: ChunkIndex,
                          channels: Container[int]) -> Optional[int]:
    """Messages of the wanted channels a chunk held, from its message indexes, or None."""
    count = 0
    try:
        for channel_id, offset in index.message_index_offsets.items():
            if channel_id in channels:
                handle.seek(offset)
                opcode, _, _, length = struct.unpack('<BQHI', handle.read(15))
                if opcode != Opcode.MESSAGE_INDEX:
                    return None
                count += length // _MESSAGE_INDEX_ENTRY
    except (OSError, struct.error):
        return None
    return count
