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
Every theory figure of steady running at one offset and input speed, from one place.

The node's diagnostics, the recording analysis and the design table all compare with (or
print) these. numpy only.
"""

from typing import NamedTuple

import numpy as np

from qrm_ros.core.kinematics.geometry import ArrayLike, float_or_array, FloatOrArray, Geometry
from qrm_ros.core.kinematics.peak_speeds import peak_ram_speeds
from qrm_ros.core.kinematics.stroke_timing import speed_ratio, stroke_times

__all__ = ['SteadyTheory', 'steady_theory']


class SteadyTheory(NamedTuple):
    """Exact figures of steady running at one offset and input speed (s, m/s, ratios)."""

    cutting_time: FloatOrArray
    return_time: FloatOrArray
    time_ratio: FloatOrArray
    speed_ratio: FloatOrArray
    peak_speed_ratio: FloatOrArray
    peak_cutting_speed: FloatOrArray
    peak_return_speed: FloatOrArray


def steady_theory(geometry: Geometry, offset: ArrayLike,
                  input_speed: ArrayLike) -> SteadyTheory:
    """
    Every theory figure of steady running, from one place.

    The node's diagnostics, the recording analysis and the design table all compare with
    (or print) these; computing them once here keeps the three from drifting apart.
    """
    cutting, returning = stroke_times(geometry, offset, input_speed)
    peak_cut, peak_return = peak_ram_speeds(geometry, offset, input_speed)
    return SteadyTheory(
        cutting_time=cutting, return_time=returning,
        time_ratio=float_or_array(np.asarray(cutting) / returning),
        speed_ratio=speed_ratio(geometry, offset, input_speed),
        peak_speed_ratio=float_or_array(np.asarray(peak_return) / peak_cut),
        peak_cutting_speed=peak_cut, peak_return_speed=peak_return)
