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
The mean cutting speed, and the offset that gives a wanted one.

The mean cutting speed is the ram's stroke over the cutting time: the figure shop tables
give. Exact, through the coupling's inverse (doc/mechanism.md).
"""

import numpy as np
from scipy.optimize import elementwise

from qrm_ros.core.common.checks import as_float, checked_input_speed, KinematicsError
from qrm_ros.core.kinematics.geometry import (ArrayLike, float_or_array, FloatOrArray, Geometry,
                                              TWO_PI)
from qrm_ros.core.kinematics.mechanism_state import forward_cut_input_arc
from qrm_ros.core.kinematics.offset_inverses import SEARCH_FRACTION
from qrm_ros.core.kinematics.stroke_timing import stroke_times

__all__ = ['mean_cutting_speed', 'offset_for_mean_cutting_speed']


def mean_cutting_speed(geometry: Geometry, offset: ArrayLike,
                       input_speed: ArrayLike) -> FloatOrArray:
    """
    Ram stroke over cutting time (m/s), exact: the cutting speed shop tables give.

    At a fixed offset it is proportional to |input_speed|, as the peak cutting speed is.
    """
    cutting, _ = stroke_times(geometry, offset, input_speed)
    return float_or_array(geometry.ram_stroke / np.asarray(cutting))


def offset_for_mean_cutting_speed(geometry: Geometry, input_speed: ArrayLike,
                                  cutting_speed: ArrayLike) -> FloatOrArray:
    """
    Offset giving a wanted mean cutting speed (m/s) at an input speed (rad/s); vectorised.

    The cut needs the input arc A = stroke |input_speed| / cutting_speed. The forward cut's
    arc is strictly monotone in the offset: differentiating the inverse coupling,
    dA/d(offset) = f(cos(a + p)) + f(cos(a - p)) with f(c) = c / sqrt(r1^2 - offset^2 c^2)
    odd and increasing (a = asin(r/h), p = crank_phase), so its sign is that of cos(p)
    (positive for the paper's p = 0: a positive offset slows the cut). The root is therefore
    unique; at cos(p) = 0 the offset leaves the cutting speed unchanged and only that one
    speed is reachable.
    """
    input_speed = checked_input_speed(input_speed)
    target = as_float('cutting_speed', cutting_speed)
    if np.any(np.asarray(target) <= 0.0):
        raise KinematicsError(f'cutting_speed must be > 0 m/s, got {cutting_speed!r}')
    arc = geometry.ram_stroke * np.abs(input_speed) / target
    forward_arc = np.where(np.asarray(input_speed) < 0.0, TWO_PI - arc, arc)
    fields = np.broadcast_arrays(forward_arc, *(np.asarray(value, dtype=float) for value in
                                                geometry.as_dict().values()))
    flat = [np.array(field, dtype=float).reshape(-1) for field in fields]
    limit = SEARCH_FRACTION * flat[1]
    below, above = (_cut_arc_error(side * limit, *flat) for side in (-1.0, 1.0))
    reachable = (np.minimum(below, above) <= 0.0) & (np.maximum(below, above) >= 0.0)
    if not np.all(reachable):
        i = int(np.argmin(reachable))
        one = Geometry(*(field[i] for field in flat[1:]))
        speed = float(np.broadcast_to(input_speed, fields[0].shape).flat[i])
        slowest, fastest = sorted(mean_cutting_speed(one, side * limit[i], speed)
                                  for side in (-1.0, 1.0))
        raise KinematicsError(
            f'cutting_speed {float(np.broadcast_to(target, fields[0].shape).flat[i]):g} m/s '
            f'is out of reach at input_speed {speed:g} rad/s: offsets with |offset| < '
            f'coupling_radius = {one.coupling_radius:g} m give mean cutting speeds from '
            f'{slowest:.6g} to {fastest:.6g} m/s')
    result = elementwise.find_root(
        _cut_arc_error, (-limit, limit), args=tuple(flat),
        tolerances={'xatol': 1e-17, 'xrtol': 4 * np.finfo(float).eps})
    return float_or_array(result.x.reshape(fields[0].shape))


def _cut_arc_error(offset, forward_arc, r1, r, h, height, phase):
    geometry = Geometry(r1, r, h, height, phase)
    return forward_cut_input_arc(geometry, offset) - forward_arc
