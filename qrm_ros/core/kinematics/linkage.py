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
Where every pin and link of the mechanism is, for drawing it (pure numpy, no ROS).

The URDF, the live markers and the animations all draw the same machine; its drawn sizes
(disc radii, lever and ram lengths, tool) and its point positions come from here only, so
the three pictures cannot disagree. Positions are in the ``shaper_base`` frame of
doc/mechanism.md (flywheel centre O2 at the origin, x right, y up), in metres, on
the plane z = 0; the joint values come from ``mechanism_state.state``.
"""

import math
from typing import NamedTuple, Optional, Tuple

import numpy as np

from qrm_ros.core.kinematics.geometry import ArrayLike, Geometry, MechanismState
from qrm_ros.core.kinematics.mechanism_state import state

__all__ = ['COLOURS', 'LinkagePoints', 'LinkageSizes', 'linkage_points', 'linkage_sizes',
           'workpiece_span']

# Colours (RGBA, 0 to 1) of the parts, by name: URDF materials, markers and animations.
COLOURS = {
    'frame_grey': (0.55, 0.55, 0.58, 1.0),
    'flywheel_blue': (0.25, 0.4, 0.7, 1.0),
    'slot_black': (0.08, 0.08, 0.1, 1.0),
    'input_orange': (0.95, 0.55, 0.1, 1.0),
    'lever_green': (0.2, 0.65, 0.3, 1.0),
    'ram_red': (0.7, 0.15, 0.15, 1.0),
    'tool_yellow': (0.95, 0.85, 0.1, 1.0),
    'pin_black': (0.1, 0.1, 0.1, 1.0),
    'workpiece_brown': (0.55, 0.4, 0.25, 1.0),
}


class LinkageSizes(NamedTuple):
    """Drawn dimensions of the parts (m); the kinematic ones are the geometry's own."""

    flywheel_radius: float      # disc of the flywheel / bull gear about O2
    input_disc_radius: float    # hub of the input crank about O1
    slot_length: float          # coupling slot on the output member, from O2 outward
    lever_length: float         # from O3 to the lever's upper end
    ram_length: float           # ram body along x, centred on its driving block
    ram_thickness: float        # ram body along y
    tool_drop: float            # tool tip below the ram line
    pin_radius: float           # pins and pivots
    bar_width: float            # cranks, lever, slot, frame lines
    ram_line_height: float      # y of the ram line in shaper_base (H - h)
    max_lever_angle: float      # the lever's swing, +/- asin(r / h) (rad)


def linkage_sizes(geometry: Geometry) -> LinkageSizes:
    """
    Drawn sizes for a (scalar) geometry.

    The slot reaches 2 r1, the farthest the coupling pin can get from O2 (|offset| < r1);
    the lever reaches past the ram block at full swing; the ram is long enough that its
    tool, at the front (-x) end, clears the flywheel at every ram position.
    """
    r1, r = geometry.coupling_radius, geometry.crank_radius
    h, height = geometry.pivot_distance, geometry.ram_height
    small = min(r1, r)
    flywheel_radius = 1.25 * r
    max_lever_angle = math.asin(r / h)
    stroke = float(geometry.ram_stroke)
    ram_length = stroke + 2.5 * flywheel_radius + 0.5 * height
    return LinkageSizes(
        flywheel_radius=flywheel_radius,
        input_disc_radius=1.25 * r1,
        slot_length=2.0 * r1,
        lever_length=1.1 * height / math.cos(max_lever_angle),
        ram_length=ram_length,
        ram_thickness=0.12 * height,
        tool_drop=0.3 * height,
        pin_radius=0.12 * small,
        bar_width=0.16 * small,
        ram_line_height=height - h,
        max_lever_angle=max_lever_angle,
    )


class LinkagePoints(NamedTuple):
    """Positions (x, y) in m of the mechanism's points; each is an array of shape (..., 2)."""

    input_centre: np.ndarray    # O1, (0, offset)
    flywheel_centre: np.ndarray  # O2, the origin
    lever_pivot: np.ndarray     # O3, (0, -h)
    coupling_pin: np.ndarray    # on the input crank at r1, sliding in the flywheel's slot
    crank_pin: np.ndarray       # on the flywheel at r, sliding in the lever's slot
    ram_block: np.ndarray       # on the lever's slot, pinned to the ram (on the ram line)
    lever_tip: np.ndarray       # the lever's upper end
    tool_tip: np.ndarray        # the cutting edge, below the ram's front (-x) end
    slot_end: np.ndarray        # outer end of the coupling slot


def linkage_points(geometry: Geometry, offset: ArrayLike, input_angle: ArrayLike,
                   mechanism_state: Optional[MechanismState] = None,
                   sizes: Optional[LinkageSizes] = None) -> LinkagePoints:
    """
    Every point of the mechanism at input angle(s) and offset(s) (broadcast, vectorised).

    ``mechanism_state`` (from ``mechanism_state.state`` at the same offset and angle) saves
    recomputing it when the caller has it; ``sizes`` likewise (``linkage_sizes``).
    """
    if mechanism_state is None:
        mechanism_state = state(geometry, offset, input_angle, 0.0)
    sizes = sizes or linkage_sizes(geometry)
    offset = np.asarray(offset, dtype=float)
    theta = np.asarray(input_angle, dtype=float)
    flywheel_angle = np.asarray(mechanism_state.flywheel_angle, dtype=float)
    lever_angle = np.asarray(mechanism_state.lever_angle, dtype=float)
    ram_position = np.asarray(mechanism_state.ram_position, dtype=float)
    shape = np.broadcast_shapes(offset.shape, theta.shape, flywheel_angle.shape)
    r1, r = geometry.coupling_radius, geometry.crank_radius
    h = geometry.pivot_distance
    crank_angle = flywheel_angle + geometry.crank_phase

    if shape == ():
        def point(x, y):  # one state (the live markers' case): no broadcasting to do
            return np.array((float(x), float(y)))
    else:
        zeros = np.zeros(shape)

        def point(x, y):
            return np.stack(np.broadcast_arrays(x + zeros, y + zeros), axis=-1)

    ram_y = sizes.ram_line_height
    return LinkagePoints(
        input_centre=point(0.0, offset),
        flywheel_centre=point(0.0, 0.0),
        lever_pivot=point(0.0, -h),
        coupling_pin=point(r1 * np.cos(theta), offset + r1 * np.sin(theta)),
        crank_pin=point(r * np.cos(crank_angle), r * np.sin(crank_angle)),
        ram_block=point(ram_position, ram_y),
        lever_tip=point(sizes.lever_length * np.sin(lever_angle),
                        -h + sizes.lever_length * np.cos(lever_angle)),
        tool_tip=point(ram_position - 0.5 * sizes.ram_length, ram_y - sizes.tool_drop),
        slot_end=point(sizes.slot_length * np.cos(flywheel_angle),
                       sizes.slot_length * np.sin(flywheel_angle)),
    )


def workpiece_span(geometry: Geometry, cutting_length: float,
                   sizes: Optional[LinkageSizes] = None) -> Tuple[float, float]:
    """
    Tool-tip x range (low, high) in m over which the tool is in the workpiece.

    The cutting load acts while the ram position is within +/- cutting_length / 2
    (doc/dynamics.md); the tool tip sits ram_length / 2 ahead of the ram block.
    """
    sizes = sizes or linkage_sizes(geometry)
    front = -0.5 * sizes.ram_length
    half = 0.5 * float(cutting_length)
    return front - half, front + half
