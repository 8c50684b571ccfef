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
Compiled (numba) loops of core.numerics.portable_math for large arrays: the C library's functions.

Each is the C library's function (math.atan2, ...) called element by element from machine
code: the same bits as Python's math, about 40 ns an element against 200 ns through Python.
numba calls the library's scalar function unless Intel's SVML is installed, with which it
would vectorise the loop with SVML's own approximations: portable_math then keeps to
Python's loop (USING_SVML). Imported only for arrays big enough to repay loading numba
(portable_math.COMPILED_MIN_ELEMENTS); compiled once per install, cached beside this file.
"""

import math

import numba
from numba.core import config

__all__ = ['arcsin', 'arctan2', 'log', 'power', 'USING_SVML']

USING_SVML = bool(getattr(config, 'USING_SVML', False))
_OPTIONS = dict(nopython=True, cache=True)


@numba.vectorize(['float64(float64, float64)'], **_OPTIONS)
def arctan2(y: float, x: float) -> float:  # pragma: no cover (compiled)
    """Return math.atan2(y, x), compiled."""
    return math.atan2(y, x)


@numba.vectorize(['float64(float64)'], **_OPTIONS)
def arcsin(x: float) -> float:  # pragma: no cover (compiled)
    """Return math.asin(x) (NaN outside [-1, 1]), compiled."""
    return math.asin(x)


@numba.vectorize(['float64(float64)'], **_OPTIONS)
def log(x: float) -> float:  # pragma: no cover (compiled)
    """Return the C library's natural logarithm (-inf at 0, NaN below), compiled."""
    return math.log(x)


@numba.vectorize(['float64(float64, float64)'], **_OPTIONS)
def power(base: float, exponent: float) -> float:  # pragma: no cover (compiled)
    """Return math.pow(base, exponent) (inf on overflow), compiled."""
    return math.pow(base, exponent)
