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
What the compiled (numba) kernels share: their compiler options and a cheap rotation.

Imported only by the kernels (qrm_ros.core.kinematics.peak_kernel,
qrm_ros.core.dynamics.torque_kernel), which load only for sweeps big enough to repay numba's
start-up.
"""

import math
from typing import Any, Callable, Optional, Tuple

import numba

__all__ = ['compiler', 'rotate']


def compiler(signature: Optional[str] = None) -> Callable[[Callable[..., Any]], Any]:
    """
    Compile with this module's options, cached on disk.

    error_model='numpy': a zero slope gives inf/NaN (refused by the safeguard), not an
    error. fastmath 'contract' only: a multiply and an add may fuse (one rounding instead of
    two; 8 % faster), no other reassociation, so every formula keeps its written order.
    """
    return numba.njit(signature, cache=True, nogil=True, error_model='numpy',
                      fastmath={'contract'})


# Taylor coefficients of sin(x)/x and cos(x) in x^2, through x^14: for |x| <= 0.3 the next
# terms are below 1e-19, so the series are as exact as the library's sin and cos.
_SIN = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(7))
_COS = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(8))
_SERIES_LIMIT = 0.3
# Below this, the first terms suffice (next ones below 1e-17 absolute).
_SHORT_SERIES_LIMIT = 1e-3


@compiler()
def rotate(sin_c: float, cos_c: float, delta: float) -> Tuple[float, float]:
    """(sin, cos) of angle + delta from those of angle, by series for small delta."""
    square = delta * delta
    if abs(delta) <= _SHORT_SERIES_LIMIT:
        sin_d = delta * (_SIN[0] + square * _SIN[1])
        cos_d = _COS[0] + square * (_COS[1] + square * _COS[2])
    elif abs(delta) <= _SERIES_LIMIT:
        sin_d = delta * (_SIN[0] + square * (_SIN[1] + square * (_SIN[2] + square * (
            _SIN[3] + square * (_SIN[4] + square * (_SIN[5] + square * _SIN[6]))))))
        cos_d = _COS[0] + square * (_COS[1] + square * (_COS[2] + square * (_COS[3] + square * (
            _COS[4] + square * (_COS[5] + square * (_COS[6] + square * _COS[7]))))))
    else:
        sin_d, cos_d = math.sin(delta), math.cos(delta)
    return sin_c * cos_d + cos_c * sin_d, cos_c * cos_d - sin_c * sin_d
