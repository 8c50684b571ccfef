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
The animation's picture: the linkage at one joint state over time-synced traces.

Every pin is drawn where ``qrm_ros.core.kinematics.linkage`` puts it for the recorded input angle,
offset and crank radius; the ram's guides and the workpiece are those of the stroke in force
in each frame. The figure draws on its own Agg canvas (no pyplot, no display): only the
moving artists are redrawn per frame, and ``drawn_points`` reads back what they show.
"""

import dataclasses
from typing import Any, Dict, Optional

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle
import numpy as np

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics.linkage import COLOURS, linkage_points, linkage_sizes, workpiece_span

# Pixels (width, height): multiples of 16, as H.264 encoders want.
FRAME_SIZE = (800, 640)
_DPI = 100


def _colour(name):
    return COLOURS[name][:3]


class LinkageFigure:
    """
    One figure redrawn per frame: the linkage on top, the time-synced traces below.

    Only the moving artists are redrawn (blitting); ``drawn_points`` reads back what they
    show, so tests can compare the picture with the kinematics core.
    """

    def __init__(self, geometry: Geometry, time: np.ndarray, ram_velocity: np.ndarray,
                 effort: Optional[np.ndarray] = None,
                 cutting_length: Optional[float] = None,
                 largest_crank_radius: Optional[float] = None) -> None:
        """
        Draw the static parts; largest_crank_radius (m) widens the view for a longer stroke.

        The drawn sizes (ram, pins, bars) are the geometry's throughout.
        """
        self.geometry = geometry
        self.sizes = sizes = linkage_sizes(geometry)
        self._cutting_length = cutting_length
        self._drawn_radius: Optional[float] = None  # the guides' and workpiece's stroke
        width, height = FRAME_SIZE
        self.figure = Figure(figsize=(width / _DPI, height / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.figure)
        grid = self.figure.add_gridspec(2, 1, height_ratios=(2.2, 1.0), left=0.1, right=0.88,
                                        top=0.90, bottom=0.08, hspace=0.25)
        self.axes = axes = self.figure.add_subplot(grid[0])
        self.trace_axes = self.figure.add_subplot(grid[1])
        self._draw_static(axes, geometry, sizes, cutting_length, max(
            float(geometry.crank_radius), largest_crank_radius or 0.0))
        line: Dict[str, Any] = dict(linewidth=4, solid_capstyle='round')
        self.slot, = axes.plot([], [], color=_colour('slot_black'), linewidth=2)
        self.crank, = axes.plot([], [], color=_colour('flywheel_blue'), **line)
        self.input_crank, = axes.plot([], [], color=_colour('input_orange'), **line)
        self.lever, = axes.plot([], [], color=_colour('lever_green'), **line)
        self.ram = Rectangle((0, 0), sizes.ram_length, sizes.ram_thickness,
                             color=_colour('ram_red'), zorder=3)
        axes.add_patch(self.ram)
        self.tool, = axes.plot([], [], color=_colour('tool_yellow'), zorder=4, **line)
        self.pivots, = axes.plot([], [], 'o', color=_colour('frame_grey'), markersize=7,
                                 markeredgecolor='black', zorder=5)
        self.pins, = axes.plot([], [], 'o', color=_colour('pin_black'), markersize=7, zorder=6)
        # Above the linkage, clear of the ram's guides.
        text: Dict[str, Any] = dict(transform=self.figure.transFigure, va='top',
                                    family='monospace', fontsize=10)
        self.label = axes.text(0.1, 0.985, '', **text)
        # The ratios change once a segment: drawn into the background, not every frame.
        self.ratios = axes.text(0.1, 0.985, '', **text)
        self._draw_traces(time, ram_velocity, effort)
        # The axes, ticks and static parts are drawn once; each frame restores them and
        # draws only the moving artists (a full redraw costs several times more).
        self.moving = [(axes, a) for a in (self.slot, self.crank, self.input_crank,
                                           self.lever, self.ram, self.tool, self.pivots,
                                           self.pins, self.label)]
        self.moving += [(self.trace_axes, self.cursor), (self.trace_axes, self.velocity_dot)]
        if self.torque_dot is not None:
            self.moving.append((self.torque_axes, self.torque_dot))
        # The guides and the workpiece follow the stroke: redrawn into the background with
        # the ratios when the crank radius changes.
        self.per_stroke = [*self.guides, *self.workpiece, self.ratios]
        for artist in [a for _, a in self.moving] + self.per_stroke:
            artist.set_animated(True)
        self.canvas.draw()
        self.bare = self.background = self.canvas.copy_from_bbox(self.figure.bbox)

    def _draw_static(self, axes, geometry, sizes, cutting_length, largest_radius):
        h = geometry.pivot_distance
        widest = dataclasses.replace(geometry, crank_radius=largest_radius)
        guide = 0.5 * (float(widest.ram_stroke) + sizes.ram_length)
        rail = 0.5 * (sizes.ram_thickness + sizes.bar_width)
        ram_y = sizes.ram_line_height
        grey = _colour('frame_grey')
        axes.plot([0, 0], [0, -h], color=grey, linewidth=6, zorder=0)
        self.guides = [axes.plot([], [], color=grey, linewidth=2, zorder=0)[0]
                       for _ in (ram_y + rail, ram_y - rail)]
        self._rails = (ram_y + rail, ram_y - rail)
        axes.add_patch(Circle((0, 0), sizes.flywheel_radius, color=_colour('flywheel_blue'),
                              alpha=0.35, zorder=1))
        top = ram_y - sizes.tool_drop
        self.workpiece = []
        if cutting_length:
            self.workpiece.append(Rectangle((0.0, top - sizes.ram_thickness), 0.0,
                                            sizes.ram_thickness,
                                            color=_colour('workpiece_brown'), zorder=1))
            axes.add_patch(self.workpiece[0])
        self._show_stroke(geometry)
        margin = 2.0 * sizes.pin_radius
        axes.set_xlim(-guide - margin, guide + margin)
        axes.set_ylim(-h - 3 * margin, ram_y + sizes.ram_thickness + 0.25 * geometry.ram_height)
        axes.set_aspect('equal', adjustable='box')
        axes.set_xlabel('x [m]')
        axes.set_ylabel('y [m]')
        axes.grid(alpha=0.3)

    def _draw_traces(self, time, ram_velocity, effort):
        axes = self.trace_axes
        axes.plot(time, ram_velocity, color=_colour('ram_red'), linewidth=1.2)
        axes.set_ylabel('ram velocity [m/s]', color=_colour('ram_red'))
        axes.set_xlabel('time [s]')
        low, high = float(np.min(time)), float(np.max(time))
        axes.set_xlim(low, high if high > low else low + 1.0)
        axes.grid(alpha=0.3)
        self.cursor = axes.axvline(low, color='black', linewidth=1)
        self.velocity_dot, = axes.plot([], [], 'o', color=_colour('ram_red'), markersize=5)
        self.torque_axes = self.torque_dot = None
        if effort is not None:
            self.torque_axes = twin = axes.twinx()
            twin.plot(time, effort, color=_colour('input_orange'), linewidth=1.2)
            twin.set_ylabel('input torque [N m]', color=_colour('input_orange'))
            self.torque_dot, = twin.plot([], [], 'o', color=_colour('input_orange'),
                                         markersize=5)

    def _show_stroke(self, geometry: Geometry) -> None:
        """Set the guides and the workpiece to the stroke of geometry (not drawn yet)."""
        guide = 0.5 * (float(geometry.ram_stroke) + self.sizes.ram_length)
        for line, y in zip(self.guides, self._rails):
            line.set_data([-guide, guide], [y, y])
        if self.workpiece and self._cutting_length:
            low, high = workpiece_span(geometry, self._cutting_length, self.sizes)
            self.workpiece[0].set_x(low)
            self.workpiece[0].set_width(high - low)
        self._drawn_radius = float(geometry.crank_radius)

    def geometry_at(self, crank_radius: Optional[float]) -> Geometry:
        """Return the geometry with a recorded crank radius (m; None: the figure's)."""
        geometry = self.geometry
        if crank_radius is not None and crank_radius != geometry.crank_radius:
            geometry = dataclasses.replace(geometry, crank_radius=crank_radius)
        return geometry

    def draw(self, input_angle: float, offset: float, time: float, ram_velocity: float,
             ratios: str, effort: Optional[float] = None,
             crank_radius: Optional[float] = None) -> np.ndarray:
        """
        Draw one state (ratios: ``ratio_text``); return it as (height, width, 3) uint8.

        crank_radius (m): the recorded one, when the stroke moved (None: the geometry's).
        """
        ratios = '\n\n' + ratios  # below the clock and the offset
        geometry = self.geometry_at(crank_radius)
        if (ratios != self.ratios.get_text()
                or float(geometry.crank_radius) != self._drawn_radius):
            self.ratios.set_text(ratios)
            self._show_stroke(geometry)
            self.canvas.restore_region(self.bare)
            for artist in self.per_stroke:
                self.axes.draw_artist(artist)
            self.background = self.canvas.copy_from_bbox(self.figure.bbox)
        self.update(input_angle, offset, time, ram_velocity, effort, crank_radius)
        self.canvas.restore_region(self.background)
        for axes, artist in self.moving:
            axes.draw_artist(artist)
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()

    def update(self, input_angle: float, offset: float, time: float, ram_velocity: float,
               effort: Optional[float] = None, crank_radius: Optional[float] = None) -> None:
        """Move the moving artists to one state, without drawing them."""
        geometry = self.geometry_at(crank_radius)
        points = linkage_points(geometry, offset, input_angle, sizes=self.sizes)
        self.slot.set_data(*zip(points.flywheel_centre, points.slot_end))
        self.crank.set_data(*zip(points.flywheel_centre, points.crank_pin))
        self.input_crank.set_data(*zip(points.input_centre, points.coupling_pin))
        self.lever.set_data(*zip(points.lever_pivot, points.lever_tip))
        block = points.ram_block
        self.ram.set_xy((block[0] - 0.5 * self.sizes.ram_length,
                         block[1] - 0.5 * self.sizes.ram_thickness))
        front = block[0] - 0.5 * self.sizes.ram_length
        self.tool.set_data([front, points.tool_tip[0]], [block[1], points.tool_tip[1]])
        self.pivots.set_data(*zip(points.input_centre, points.flywheel_centre,
                                  points.lever_pivot))
        self.pins.set_data(*zip(points.coupling_pin, points.crank_pin, points.ram_block))
        self.label.set_text(f't = {time:8.3f} s\noffset {offset * 1e3:+7.2f} mm')
        self.cursor.set_xdata([time, time])
        self.velocity_dot.set_data([time], [ram_velocity])
        if self.torque_dot is not None:
            self.torque_dot.set_data([time], [effort])

    def drawn_points(self) -> Dict[str, np.ndarray]:
        """Return what the moving artists show now: name -> (x, y) in m (traces: s, m/s)."""
        def ends(line):
            x, y = line.get_data()
            return np.array((x[0], y[0])), np.array((x[-1], y[-1]))

        pivots = np.column_stack(self.pivots.get_data())
        pins = np.column_stack(self.pins.get_data())
        x, y = self.ram.get_xy()
        drawn = {
            'input_centre': pivots[0], 'flywheel_centre': pivots[1], 'lever_pivot': pivots[2],
            'coupling_pin': pins[0], 'crank_pin': pins[1], 'ram_block': pins[2],
            'input_crank': np.array(ends(self.input_crank)),
            'crank': np.array(ends(self.crank)),
            'slot': np.array(ends(self.slot)),
            'lever': np.array(ends(self.lever)),
            'tool_tip': ends(self.tool)[1],
            'ram_centre': np.array((x + 0.5 * self.ram.get_width(),
                                    y + 0.5 * self.ram.get_height())),
            'velocity_dot': np.column_stack(self.velocity_dot.get_data())[0],
            'guide': np.array(self.guides[0].get_data()[0]),
            'cursor_time': float(self.cursor.get_xdata()[0]),
        }
        if self.torque_dot is not None:
            drawn['torque_dot'] = np.column_stack(self.torque_dot.get_data())[0]
        return drawn

    def close(self) -> None:
        """Free the figure's artists (the canvas holds no window)."""
        self.figure.clear()
