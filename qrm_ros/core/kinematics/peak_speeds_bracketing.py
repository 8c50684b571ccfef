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
The previous peak-speed method, kept as the reference of tests and the benchmark's baseline.

Slower than qrm_ros.core.kinematics.peak_speeds but built only from state() and scipy's root
finder, so it checks the closed-form slopes there independently.
"""

from typing import Any, List, Tuple

import numpy as np
from scipy.optimize import elementwise

from qrm_ros.core.kinematics.geometry import ArrayLike, check_offset, Geometry, TWO_PI
from qrm_ros.core.kinematics.mechanism_state import (input_angle_for_flywheel_angle,
                                                     reversal_flywheel_angles, state)

__all__ = ['peak_speeds_bracketing']


def peak_speeds_bracketing(geometry: Geometry, offset: ArrayLike,
                           samples: int = 48) -> Tuple[np.ndarray, np.ndarray]:
    """
    Run the previous method, kept as the reference of tests and the benchmark's baseline.

    Forward (cutting, return) peaks per unit input speed: extrema bracketed on a grid of
    flywheel angles, each solved where the ram acceleration crosses zero by scipy's
    vectorised Chandrupatla root finder, every evaluation through state().
    """
    offset = np.asarray(check_offset(geometry, offset), dtype=float)
    shape = np.broadcast_shapes(offset.shape, *(np.shape(v) for v in geometry.as_dict().values()))
    fields: List[Any] = [np.broadcast_to(np.asarray(v, dtype=float), shape).reshape(-1)
                         for v in [offset] + list(geometry.as_dict().values())]
    reversals: Any = reversal_flywheel_angles(Geometry(*fields[1:]))
    start, end = reversals
    fraction = np.linspace(0.0, 1.0, samples + 1)[1:-1]
    peaks = []
    for arc_start, arc_end in ((start, end), (end, start + TWO_PI)):
        grid = arc_start[:, None] + (arc_end - arc_start)[:, None] * fraction[None, :]
        args = [f[:, None] for f in fields]
        sampled = _state_on_arc(grid, *args)
        best = np.abs(sampled.ram_velocity).max(axis=1)
        # d|v|/dt changes sign from + to - at a speed maximum: v * a goes + -> -.
        growth = sampled.ram_velocity * sampled.ram_acceleration
        rows, cols = np.nonzero((growth[:, :-1] > 0.0) & (growth[:, 1:] <= 0.0))
        if rows.size:
            row_args = [f[rows] for f in fields]
            result = elementwise.find_root(
                _bracketing_growth, (grid[rows, cols], grid[rows, cols + 1]),
                args=tuple(row_args),
                tolerances={'xatol': 1e-15, 'xrtol': 4 * np.finfo(float).eps})
            at_root = np.abs(_state_on_arc(result.x, *row_args).ram_velocity)
            np.maximum.at(best, rows, at_root)
        peaks.append(best.reshape(shape))
    return peaks[0], peaks[1]


def _state_on_arc(flywheel_angle, offset, r1, r, h, height, phase):
    geometry = Geometry(r1, r, h, height, phase)
    theta = input_angle_for_flywheel_angle(geometry, offset, flywheel_angle)
    return state(geometry, offset, theta, 1.0)


def _bracketing_growth(flywheel_angle, *args):
    sampled = _state_on_arc(flywheel_angle, *args)
    return sampled.ram_velocity * sampled.ram_acceleration
