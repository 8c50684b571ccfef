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
The public input checks of the core, and the error they raise.

Every model function refuses what the mechanism cannot take with a message that names the
input, its unit and the value given; the checks live here once so the messages cannot drift
apart. numpy only.
"""

import math
from typing import Any, Type, Union

import numpy as np

__all__ = ['KinematicsError', 'as_float', 'checked_input_speed', 'finite', 'positive']


class KinematicsError(ValueError):
    """A geometry, offset or target the mechanism cannot take; the message names it."""


def _not_a_real_number(name: str, value: Any, unit: str,
                       error: Type[KinematicsError]) -> KinematicsError:
    return error(f'{name} must be a real number in {unit}, got {value!r}')


def as_float(name: str, value: Any, unit: Union[str, None] = None,
             error: Type[KinematicsError] = KinematicsError,
             refuse_bool: bool = False) -> Union[float, np.ndarray]:
    """
    Return a real, finite number as a float, or an array of them as an array.

    With a unit the messages name it; refuse_bool also refuses True and False (a flag
    passed where a number belongs).
    """
    if refuse_bool and isinstance(value, bool):
        raise _not_a_real_number(name, value, str(unit), error)
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        if unit is None:
            raise error(f'{name} must be a real number, got {value!r}') from None
        raise _not_a_real_number(name, value, unit, error) from None
    if not np.all(np.isfinite(array)):
        shown_unit = '' if unit is None else f' ({unit})'
        raise error(f'{name} must be finite{shown_unit}, got {value!r}')
    return float(array) if array.ndim == 0 else array


def finite(name: str, value: Any, unit: str,
           error: Type[KinematicsError] = KinematicsError) -> float:
    """Return one real, finite number as a float (refusing bools, arrays and text)."""
    if isinstance(value, bool):
        raise _not_a_real_number(name, value, unit, error)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise _not_a_real_number(name, value, unit, error) from None
    if not math.isfinite(number):
        raise error(f'{name} must be finite ({unit}), got {number!r}')
    return number


def positive(name: str, value: Any, unit: str,
             error: Type[KinematicsError] = KinematicsError) -> float:
    """Return one real number > 0 as a float."""
    number = finite(name, value, unit, error)
    if number <= 0.0:
        raise error(f'{name} must be > 0 {unit}, got {number!r}')
    return number


def checked_input_speed(input_speed: Any) -> Union[float, np.ndarray]:
    """Return the input speed (rad/s, float or array), refusing zero: no strokes then."""
    input_speed = as_float('input_speed', input_speed)
    if np.any(np.asarray(input_speed) == 0.0):
        raise KinematicsError('input_speed must be non-zero (rad/s): a stopped shaft has no '
                              'strokes')
    return input_speed
