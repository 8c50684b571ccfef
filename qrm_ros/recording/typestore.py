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

import operator
import threading
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

__all__ = ['exact_cdr', 'jazzy_typestore', 'preload_typestore', 'store_message']

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


# numpy's types of the primitive arrays and sequences in rosbags' messages.
_ARRAY_TYPES = {
    'boolean': np.bool_, 'uint8': np.uint8, 'int8': np.int8, 'int16': np.int16,
    'uint16': np.uint16, 'int32': np.int32, 'uint32': np.uint32, 'int64': np.int64,
    'uint64': np.uint64, 'float': np.float32, 'double': np.float64}


def _element_type(field_type: str) -> str:
    """Return the element type of an array or sequence field type ('' for a single value)."""
    if field_type.startswith('sequence<'):
        return field_type[len('sequence<'):-1].split(',')[0].strip()
    if field_type.endswith(']'):
        return field_type[:field_type.index('[')]
    return ''


def _single(value: Any) -> Any:
    """Return a one-byte field (rclpy: bytes, or a str for an IDL char) as the store's integer."""
    if isinstance(value, bytes):
        return value[0]
    return ord(value) if isinstance(value, str) else value


def _field_converter(field_type: str) -> Optional[Callable[[Any], Any]]:
    """Return how one field's rclpy value becomes the store's (None: as it is)."""
    element = _element_type(field_type)
    if element:
        if '/' in element:
            return lambda values: [store_message(value) for value in values]
        if element in ('octet', 'char'):  # rclpy: a bytes object each
            return lambda values: np.array([_single(value) for value in values], dtype=np.uint8)
        if element in _ARRAY_TYPES:
            dtype = _ARRAY_TYPES[element]
            return lambda values: np.array(values, dtype=dtype)
        return list  # strings
    if '/' in field_type:
        return store_message
    if field_type in ('octet', 'char'):
        return _single
    return None


# rclpy message class -> (the store's class, the fields' getter, (index, converter) of those
# that change)
_PLANS: Dict[Any, Tuple[Any, Callable[[Any], Any], Tuple[Tuple[int, Any], ...]]] = {}


def store_message(message: Any) -> Any:
    """Return an rclpy message as the type store's message of the same values."""
    message_class = type(message)
    plan = _PLANS.get(message_class)
    if plan is None:  # once per class (a race only works it out twice)
        fields = message_class.get_fields_and_field_types()
        package = message_class.__module__.split('.')[0]
        store_class = jazzy_typestore().types[f'{package}/msg/{message_class.__name__}']
        converters = [_field_converter(kind) for kind in fields.values()]
        names = list(fields)
        getter = (operator.attrgetter(*names) if len(names) > 1 else
                  lambda message: (getattr(message, names[0]),))
        plan = _PLANS[message_class] = (store_class, getter, tuple(
            (index, convert) for index, convert in enumerate(converters)
            if convert is not None))
    store_class, getter, conversions = plan
    values = list(getter(message))
    for index, convert in conversions:
        values[index] = convert(values[index])
    return store_class(*values)


def exact_cdr(message: Any, type_name: str) -> bytes:
    """
    Return an rclpy message's CDR bytes as DDS sends them: their exact length, zero padding.

    rclpy's serialize_message (rmw_serialize on Fast DDS) returns the size it estimated, not
    the size it wrote (8 bytes more for an rcl_interfaces/msg/ParameterEvent, which rosbags
    then refuses to read), and leaves the alignment padding as it found the memory. So the
    message's values are handed to the type store's classes and encoded by its encoder: the
    bytes of rclpy's message decoded by the store and encoded again, at a quarter of that
    cost (a test holds the two together).
    """
    return bytes(jazzy_typestore().serialize_cdr(store_message(message), type_name))
