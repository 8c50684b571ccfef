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
The offset that gives a wanted speed ratio, time ratio or peak cutting speed.

Each figure is inverted numerically over |offset| < r1 (the speed ratio in closed form,
paper eq. 27, when the crank phase is 0); the smallest-|offset| solution is returned.
"""

import math

import numpy as np
from scipy import optimize

from qrm_ros.core.common.checks import as_float, checked_input_speed, KinematicsError
from qrm_ros.core.kinematics.geometry import ArrayLike, check_offset, FloatOrArray, Geometry
from qrm_ros.core.kinematics.peak_speeds import peak_ram_speeds
from qrm_ros.core.kinematics.stroke_timing import speed_ratio, time_ratio

__all__ = ['SEARCH_FRACTION', 'offset_for_cutting_speed', 'offset_for_speed_ratio',
           'offset_for_time_ratio']

# Inversions search |offset| <= this fraction of r1 (the open limit, short of the singularity).
SEARCH_FRACTION = 1.0 - 1e-9


def offset_for_speed_ratio(geometry: Geometry, speed_ratio_target: ArrayLike) -> FloatOrArray:
    """Offset giving a mid-stroke speed ratio (eq. 27; numerical inversion if phased)."""
    target = as_float('speed_ratio', speed_ratio_target)
    if target <= 0.0:
        raise KinematicsError(f'speed_ratio must be > 0, got {speed_ratio_target!r}')
    if geometry.crank_phase == 0.0:
        r1, r, h = geometry.coupling_radius, geometry.crank_radius, geometry.pivot_distance
        offset = r1 * (target * (h - r) - (h + r)) / (target * (h - r) + (h + r))
        return check_offset(geometry, offset)
    return _invert(lambda d: speed_ratio(geometry, d), target, geometry, 'speed_ratio')


def offset_for_time_ratio(geometry: Geometry, time_ratio_target: ArrayLike) -> FloatOrArray:
    """Offset giving a wanted time ratio (forward running), by inverting the exact TR."""
    target = as_float('time_ratio', time_ratio_target)
    return _invert(lambda d: time_ratio(geometry, d), target, geometry, 'time_ratio')


def offset_for_cutting_speed(geometry: Geometry, input_speed: ArrayLike,
                             cutting_speed: ArrayLike) -> FloatOrArray:
    """Offset giving a wanted peak cutting speed (m/s) at an input speed (rad/s)."""
    input_speed = checked_input_speed(input_speed)
    target = as_float('cutting_speed', cutting_speed)
    return _invert(lambda d: peak_ram_speeds(geometry, d, input_speed)[0], target, geometry,
                   'cutting_speed')


def _invert(function, target, geometry, name):
    """
    Smallest-|offset| solution of function(offset) = target over |offset| < r1.

    Brackets come from a grid dense near the ends (where the mechanism changes fastest);
    each is then solved to machine precision with Brent's method.
    """
    limit = SEARCH_FRACTION * geometry.coupling_radius
    offsets = limit * np.sin(np.linspace(-0.5 * math.pi, 0.5 * math.pi, 801))
    values = np.asarray(function(offsets)) - target
    exact = np.nonzero(values == 0.0)[0]
    candidates = [offsets[i] for i in exact]
    for i in np.nonzero(values[:-1] * values[1:] < 0.0)[0]:
        candidates.append(optimize.brentq(lambda d: float(function(d)) - target,
                                          offsets[i], offsets[i + 1], xtol=1e-17,
                                          rtol=4 * np.finfo(float).eps))
    if not candidates:
        low, high = np.min(values) + target, np.max(values) + target
        raise KinematicsError(
            f'{name} {target:g} is out of reach: offsets with |offset| < coupling_radius = '
            f'{geometry.coupling_radius:g} m give {name} from {low:.6g} to {high:.6g}')
    return float(min(candidates, key=abs))
