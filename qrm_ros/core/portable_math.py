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
Transcendental functions whose bits do not follow numpy's choice of vector code.

numpy computes arctan2, arcsin, log, power (and the other inverse and exponential
functions) with its own vector code where the CPU has AVX-512, and with the C library's
elsewhere: an AVX-512 machine's results differ in the last bit for a few percent of inputs
(arctan2: 8 %), for scalars and arrays alike. The paths whose bits the docs promise
(doc/reproducibility.md) call these instead: the C library's functions (Python's math)
element by element, with numpy's answers where the C library refuses (log(0) = -inf, a
domain error: NaN). numpy's sin, cos, sqrt and hypot take no such vector code: they need
no stand-in. About 0.1 us an element, 0.3 us a scalar call.
"""

import math
from typing import Any, Callable

import numpy as np
import numpy.typing as npt

__all__ = ['arcsin', 'arctan2', 'log', 'power']

ArrayLike = npt.ArrayLike
# As numpy's: a numpy float for scalars, an array of the broadcast shape otherwise (typed
# Any, as numpy's own ufuncs are, so callers keep the type they use).
FloatOrArray = Any


def _elementwise(function: Callable[..., float], fallback: Callable[..., Any],
                 *arguments: ArrayLike) -> Any:
    """Apply function to every element (broadcast), fallback where it raises; numpy's types."""
    def safe(*values):
        try:
            return function(*values)
        except (ValueError, OverflowError):
            with np.errstate(all='ignore'):
                return float(fallback(*values))
    if all(isinstance(argument, float) for argument in arguments):  # the common scalar call
        return np.float64(safe(*arguments))
    arrays = [np.asarray(argument, dtype=float) for argument in arguments]
    if not any(array.ndim for array in arrays):
        return np.float64(safe(*(float(array) for array in arrays)))
    broadcast = np.broadcast_arrays(*arrays)
    values = map(safe, *(array.ravel().tolist() for array in broadcast))
    return np.fromiter(values, dtype=float, count=broadcast[0].size).reshape(broadcast[0].shape)


def arctan2(y: ArrayLike, x: ArrayLike) -> FloatOrArray:
    """Return the angle of the point (x, y) (rad), as numpy.arctan2, by the C library."""
    return _elementwise(math.atan2, np.arctan2, y, x)


def arcsin(x: ArrayLike) -> FloatOrArray:
    """Return the arc sine (rad; NaN outside [-1, 1]), as numpy.arcsin, by the C library."""
    return _elementwise(math.asin, np.arcsin, x)


def log(x: ArrayLike) -> FloatOrArray:
    """Return the natural logarithm (-inf at 0, NaN below), as numpy.log, by the C library."""
    return _elementwise(math.log, np.log, x)


def power(base: ArrayLike, exponent: ArrayLike) -> FloatOrArray:
    """Return base to the power exponent (inf on overflow), as numpy.power, by the C library."""
    return _elementwise(math.pow, np.power, base, exponent)
