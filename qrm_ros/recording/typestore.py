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
rosbags' Jazzy type store, loaded once: how the project reads and writes messages without rclpy.

It holds every Jazzy type (``tf2_msgs`` too, which is not on the package index); the
recorder's machine channels, the offline simulator and the analysis all use this one store.
"""

import threading
from typing import Any, List

__all__ = ['canonical_cdr', 'jazzy_typestore', 'preload_typestore']

_TYPESTORE: List[Any] = []
_TYPESTORE_LOCK = threading.Lock()


def jazzy_typestore() -> Any:
    """Return the Jazzy type store (loaded on first use; it compiles a codec per type once)."""
    # About 0.1 s to load (seconds on a loaded machine): once, when first needed or ahead of
    # time by preload_typestore.
    with _TYPESTORE_LOCK:
        if not _TYPESTORE:
            from rosbags.typesys import get_typestore, Stores
            _TYPESTORE.append(get_typestore(Stores.ROS2_JAZZY))
        return _TYPESTORE[0]


def preload_typestore() -> None:
    """
    Load the type store on a thread of its own, now.

    The recorder calls it when it starts, so that the load does not stall its subscriptions
    when the geometry arrives (the import gives up the GIL every few milliseconds).
    """
    threading.Thread(target=jazzy_typestore, name='typestore_preload', daemon=True).start()


def canonical_cdr(data: bytes, type_name: str) -> bytes:
    """
    Return a message's CDR bytes as DDS sends them: their exact length, zeros in the padding.

    rclpy's serialize_message (rmw_serialize on Fast DDS) returns the size it estimated, not
    the size it wrote (8 bytes more for an rcl_interfaces/msg/ParameterEvent, which rosbags
    then refuses to read), and leaves the alignment padding as it found the memory. The
    message is decoded by the type store's own decoder, which stops where the message ends,
    and encoded again.
    """
    store = jazzy_typestore()
    definition = store.get_msgdef(type_name)
    decode = (definition.deserialize_cdr_le if data[1] else definition.deserialize_cdr_be)
    message, _ = decode(memoryview(data)[4:], 0, definition.cls, store)
    return bytes(store.serialize_cdr(message, type_name, little_endian=bool(data[1])))
