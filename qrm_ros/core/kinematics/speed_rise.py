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
The sign test of the peak-speed search, one formula for numpy and for the compiled kernel.

numpy only (no numba): qrm_ros.core.kinematics.peak_speeds samples it on arrays, and
qrm_ros.core.kinematics.peak_kernel compiles this same function for its scalar loop.
"""

import numpy as np

from qrm_ros.core.kinematics.geometry import ArrayLike, FloatOrArray

__all__ = ['speed_rise_of']


def speed_rise_of(sin_c: ArrayLike, cos_c: ArrayLike, r1: ArrayLike, r: ArrayLike,
                  h: ArrayLike, cos0: ArrayLike, sin0: ArrayLike,
                  offset: ArrayLike) -> FloatOrArray:
    """
    Return peak_speeds.speed_rise from the crank angle's sine and cosine (arrays or floats).

    d|v|/dphi_c times a factor of the sign of h sin(phi_c) + r, with one square root and
    no division (the derivation is peak_speeds.speed_rise's).
    """
    offset_cos = offset * (cos_c * cos0 + sin_c * sin0)
    offset_sin = offset * (sin_c * cos0 - cos_c * sin0)
    root2 = r1 * r1 - offset_cos * offset_cos
    lever = (h * sin_c + r) * (h + r * sin_c)
    return (cos_c * ((h * h - 2.0 * r * r) - h * r * sin_c) * root2
            - offset_cos * (np.sqrt(root2) - offset_sin) * lever)
