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
The drive's dimensions and the offset's range.

numpy only: a command that needs no more than the geometry's names (the recorder) does not
load scipy. Frame and symbols as doc/mechanism.md: the flywheel centre O2 at the origin, the
input shaft O1 at (0, offset), the lever pivot O3 at (0, -pivot_distance).
"""

from dataclasses import dataclass, fields
import math
from typing import Any, Dict, NamedTuple, Optional, Tuple, Union

import numpy as np

from qrm_ros.core.common.checks import as_float, KinematicsError

# KinematicsError is checks' (the error every input check raises), named here too: the
# geometry's callers catch it.
__all__ = ['ArrayLike', 'FloatOrArray', 'Geometry', 'KinematicsError', 'MechanismState',
           'SAFE_OFFSET_FRACTION', 'TWO_PI', 'check_offset', 'crank_radius_for_stroke',
           'float_or_array', 'stroke_for_crank_radius']

TWO_PI = 2.0 * math.pi
# Fraction of the coupling radius an offset may use in operation: at |offset| = r1 the pin
# crosses the output axis and the flywheel speed is unbounded; at 0.9 r1 it peaks at 10x.
SAFE_OFFSET_FRACTION = 0.9


# A float for scalar arguments, an array of their broadcast shape otherwise; arguments
# take the same (numbers or numpy arrays, broadcast together).
FloatOrArray = Union[float, np.ndarray]
ArrayLike = FloatOrArray


def float_or_array(value: Any) -> FloatOrArray:
    """Return a 0-d result as a float, any other as it is (the FloatOrArray convention)."""
    return float(value) if np.ndim(value) == 0 else value


@dataclass(frozen=True, eq=False)
class Geometry:
    """
    Dimensions of the drive, in metres and radians.

    Fields may be numpy arrays (broadcast against offsets and angles) for design sweeps.
    """

    coupling_radius: float
    crank_radius: float
    pivot_distance: float
    ram_height: float = 0.2
    crank_phase: float = 0.0

    def __post_init__(self) -> None:
        for name in ('coupling_radius', 'crank_radius', 'pivot_distance', 'ram_height'):
            value = as_float(name, getattr(self, name))
            if np.any(np.asarray(value) <= 0.0):
                raise KinematicsError(f'{name} must be > 0 m, got {getattr(self, name)!r}')
            object.__setattr__(self, name, value)
        object.__setattr__(self, 'crank_phase', as_float('crank_phase', self.crank_phase))
        if np.any(np.asarray(self.crank_radius) >= self.pivot_distance):
            raise KinematicsError(
                f'crank_radius ({self.crank_radius!r} m) must be smaller than pivot_distance '
                f'({self.pivot_distance!r} m): otherwise the lever turns fully round instead '
                'of swinging')

    @classmethod
    def paper(cls, ram_height: float = 0.2) -> 'Geometry':
        """Return Table 1 of the source article: r1 = 25 mm, r = 50.5 mm, h = 113 mm."""
        return cls(coupling_radius=0.025, crank_radius=0.0505, pivot_distance=0.113,
                   ram_height=ram_height)

    @property
    def max_safe_offset(self) -> FloatOrArray:
        """
        Largest |offset| the node accepts (SAFE_OFFSET_FRACTION of the coupling radius).

        Rounded to 15 significant digits, so limits read 0.0225, not 0.022500000000000003.
        """
        limit = SAFE_OFFSET_FRACTION * self.coupling_radius
        return float(f'{limit:.15g}') if np.ndim(limit) == 0 else limit

    @property
    def ram_stroke(self) -> FloatOrArray:
        """Distance between the ram's two reversal points (independent of the offset)."""
        return stroke_for_crank_radius(self.crank_radius, self.pivot_distance, self.ram_height)

    @classmethod
    def field_names(cls) -> Tuple[str, ...]:
        """Names of the fields, in order: the node's geometry parameters and metadata keys."""
        return tuple(field.name for field in fields(cls))

    def as_dict(self) -> Dict[str, FloatOrArray]:
        return {name: getattr(self, name) for name in self.field_names()}


def stroke_for_crank_radius(crank_radius: ArrayLike, pivot_distance: ArrayLike,
                            ram_height: ArrayLike) -> FloatOrArray:
    """
    Ram stroke (m) of a crank radius: 2 H r / sqrt(h^2 - r^2), for 0 < r < h.

    The ram reverses where the lever is tangent to the crank circle, tan(psi) = +-r /
    sqrt(h^2 - r^2), and x = H tan(psi). The offset does not change it.
    """
    r, h = crank_radius, pivot_distance
    return 2.0 * ram_height * r / np.sqrt(h * h - r * r)


def crank_radius_for_stroke(stroke: ArrayLike, pivot_distance: ArrayLike,
                            ram_height: ArrayLike) -> FloatOrArray:
    """Crank radius (m) that gives a ram stroke S (m): S h / sqrt(4 H^2 + S^2), always < h."""
    return stroke * pivot_distance / np.sqrt(4.0 * ram_height * ram_height + stroke * stroke)


class MechanismState(NamedTuple):
    """Positions and rates of every joint at one instant (rad, rad/s, m, m/s, m/s^2)."""

    flywheel_angle: FloatOrArray
    flywheel_speed: FloatOrArray
    lever_angle: FloatOrArray
    lever_speed: FloatOrArray
    ram_position: FloatOrArray
    ram_velocity: FloatOrArray
    ram_acceleration: FloatOrArray


def check_offset(geometry: 'Geometry', offset: ArrayLike,
                 limit: Optional[float] = None) -> FloatOrArray:
    """
    Refuse an offset the coupling cannot turn with; return it as float or array.

    ``limit`` defaults to the coupling radius (the physical limit, exclusive); the node
    passes ``geometry.max_safe_offset`` (inclusive).
    """
    offset = as_float('offset', offset)
    if limit is None:
        bad = np.abs(offset) >= geometry.coupling_radius
        allowed = f'|offset| < coupling_radius = {_fmt(geometry.coupling_radius)} m'
    else:
        bad = np.abs(offset) > limit
        allowed = f'|offset| <= {_fmt(limit)} m'
    if np.any(bad):
        shown = float(np.asarray(offset)[np.asarray(bad)].flat[0]) if np.ndim(offset) else offset
        raise KinematicsError(f'offset {shown!r} m is out of range: allowed {allowed}')
    return offset


def _fmt(value):
    return f'{value:.6g}' if np.ndim(value) == 0 else 'per-element values'
