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
(doc/reproducibility.md) call these instead: the C library's functions element by element,
through Python's math (0.2 us an element, 1 us a scalar call) or, for arrays of
COMPILED_MIN_ELEMENTS or more, through compiled loops (core.numerics.portable_math_kernel, 40 ns an
element), which give the same bits. Where the library refuses (log(0), a domain error,
an overflow), the answer is numpy's: -inf, NaN, inf. Every NaN comes out as numpy's default
NaN. numpy's sin, cos, sqrt and hypot take no such vector code: they need no stand-in.
"""

import math
from types import SimpleNamespace
from typing import Any, Callable, Optional

import numpy as np
import numpy.typing as npt

__all__ = ['ARRAY_OPS', 'arcsin', 'arctan2', 'COMPILED_MIN_ELEMENTS', 'log', 'power',
           'SCALAR_OPS']

ArrayLike = npt.ArrayLike
# As numpy's: a numpy float for scalars, an array of the broadcast shape otherwise (typed
# Any, as numpy's own ufuncs are, so callers keep the type they use).
FloatOrArray = Any
# Arrays of this many elements or more take the compiled loops: loading numba takes 0.3 s
# once a process (as long as 1.5 x 10^6 elements through Python), and a sweep this large
# loads it for its peak searches too (peak_speeds.COMPILED_MIN_CONFIGURATIONS).
COMPILED_MIN_ELEMENTS = 50_000


def _compiled(name: str) -> Optional[Callable[..., np.ndarray]]:
    """Return the compiled loop of a function, or None (no numba, or numba with SVML)."""
    try:
        # Deferred: numba is heavy (0.3 s or more to load) and optional; only large arrays
        # come here.
        from qrm_ros.core.numerics import portable_math_kernel
    except ImportError:
        return None
    return None if portable_math_kernel.USING_SVML else getattr(portable_math_kernel, name)


def _elementwise(name: str, function: Callable[..., float], fallback: Callable[..., Any],
                 *arguments: ArrayLike) -> Any:
    """Apply function to every element (broadcast), fallback where it raises; numpy's types."""
    def safe(*values):
        try:
            value = function(*values)
        except (ValueError, OverflowError):
            with np.errstate(all='ignore'):
                value = float(fallback(*values))
        return math.nan if value != value else value
    if all(isinstance(argument, float) for argument in arguments):  # the common scalar call
        return np.float64(safe(*arguments))
    arrays = [np.asarray(argument, dtype=float) for argument in arguments]
    if not any(array.ndim for array in arrays):
        return np.float64(safe(*(float(array) for array in arrays)))
    broadcast = np.broadcast_arrays(*arrays)
    compiled = _compiled(name) if broadcast[0].size >= COMPILED_MIN_ELEMENTS else None
    if compiled is not None:
        with np.errstate(all='ignore'):
            result = compiled(*broadcast)
        result[np.isnan(result)] = math.nan
        return result
    values = map(safe, *(array.ravel().tolist() for array in broadcast))
    return np.fromiter(values, dtype=float, count=broadcast[0].size).reshape(broadcast[0].shape)


def arctan2(y: ArrayLike, x: ArrayLike) -> FloatOrArray:
    """Return the angle of the point (x, y) (rad), as numpy.arctan2, by the C library."""
    return _elementwise('arctan2', math.atan2, np.arctan2, y, x)


def arcsin(x: ArrayLike) -> FloatOrArray:
    """Return the arc sine (rad; NaN outside [-1, 1]), as numpy.arcsin, by the C library."""
    return _elementwise('arcsin', math.asin, np.arcsin, x)


def log(x: ArrayLike) -> FloatOrArray:
    """Return the natural logarithm (-inf at 0, NaN below), as numpy.log, by the C library."""
    return _elementwise('log', math.log, np.log, x)


def power(base: ArrayLike, exponent: ArrayLike) -> FloatOrArray:
    """Return base to the power exponent (inf on overflow), as numpy.power, by the C library."""
    return _elementwise('power', math.pow, np.power, base, exponent)


# The functions the closed forms (kinematics, the efforts' chain) take: Python's math for one
# sample of floats (20 times faster than numpy on floats), numpy's for arrays but arctan2
# the C library's: an array's element gets the bits a float gets.
SCALAR_OPS = SimpleNamespace(sin=math.sin, cos=math.cos, sqrt=math.sqrt, atan2=math.atan2)
ARRAY_OPS = SimpleNamespace(sin=np.sin, cos=np.cos, sqrt=np.sqrt, atan2=arctan2)
