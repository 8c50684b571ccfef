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
The linkage as ``visualization_msgs/MarkerArray``, for RViz and Foxglove.

They draw it without a URDF or any transform: every point is in the node's ``frame_id``.

No node here: the node calls :func:`linkage_marker_array` at its ``marker_rate`` and
publishes the result, and :func:`delete_all_marker_array` on reset. Each call is small
(a 30 Hz publisher beside a 1 kHz loop): what depends only on the geometry is computed
once per geometry, the ratios once per offset, and only the moving points per call.

Every marker has a stable namespace and id (``MARKER_KEYS``); a part that is absent (the
workpiece without a cutting load) is sent as DELETE under its own key, so it disappears.
``moving_only=True`` gives the markers that move with the input angle (``MOVING_KEYS``)
alone: the others change only with the offset, the direction or the loads, and markers stay
until replaced, so a publisher can send them only then (rclpy's conversion of the whole
array costs about 115 us, of the moving part 58 us; each marker about 12 us, so the bars
share one).
Points lie on z = 0 (the flywheel disc sits just behind it): marker points are the core's
pin positions exactly.
"""

import functools

from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.linkage import COLOURS, linkage_points, linkage_sizes, workpiece_span
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND

__all__ = ['LINK_BARS', 'MARKER_KEYS', 'MOVING_KEYS', 'delete_all_marker_array', 'label_text',
           'linkage_marker_array', 'stamp_message']

# (namespace, id) of every marker, in the order of the array.
MARKER_KEYS = (
    ('frame', 0), ('flywheel', 0), ('coupling_slot', 0), ('links', 0), ('ram', 0), ('pins', 0),
    ('pivots', 0), ('workpiece', 0), ('label', 0),
)
# The markers whose points move with the input angle at a fixed offset, in the array's order.
MOVING_KEYS = (('coupling_slot', 0), ('links', 0), ('ram', 0), ('pins', 0))
# The bars of the 'links' marker in its order, with their colours (linkage.COLOURS): a
# LINE_LIST, two points and two colours a bar.
LINK_BARS = (('input_crank', 'input_orange'), ('crank', 'flywheel_blue'),
             ('lever', 'lever_green'), ('tool', 'tool_yellow'))


def _colour(name, alpha=None):
    red, green, blue, opaque = COLOURS[name]
    return ColorRGBA(r=red, g=green, b=blue, a=opaque if alpha is None else alpha)


def stamp_message(stamp):
    """Return a builtin_interfaces Time for a stamp in integer nanoseconds (a Time as it is)."""
    if isinstance(stamp, Time):
        return stamp
    seconds, nanoseconds = divmod(int(stamp), NANOSECONDS_PER_SECOND)
    return Time(sec=seconds, nanosec=nanoseconds)


def _point(xy, z=0.0):
    return Point(x=float(xy[0]), y=float(xy[1]), z=z)


def _set(point, xy):
    point.x, point.y = float(xy[0]), float(xy[1])


class _Markers:
    """
    The markers of one geometry, built once; each call moves their points.

    Building a Marker costs tens of microseconds in rclpy (it holds a dozen nested
    messages); setting a coordinate, well under one. All markers share one header.
    """

    def __init__(self, geometry):
        self.sizes = sizes = linkage_sizes(geometry)
        self.stroke = float(geometry.ram_stroke)  # m, shown in the label
        self.header = header = Header()
        h = geometry.pivot_distance
        width = sizes.bar_width
        line = (width, 0.0, 0.0)
        pin = (2.0 * sizes.pin_radius,) * 3
        ram_y = sizes.ram_line_height
        guide = 0.5 * (float(geometry.ram_stroke) + sizes.ram_length)
        rail = 0.5 * (sizes.ram_thickness + width)
        origin = (0.0, 0.0)

        def marker(key, kind, colour, scale, points=(), position=origin, z=0.0):
            namespace, number = key
            built = Marker(header=header, ns=namespace, id=number, type=kind,
                           action=Marker.ADD, color=colour, lifetime=Duration(),
                           points=[_point(p) for p in points])
            built.scale.x, built.scale.y, built.scale.z = scale
            built.pose.position = _point(position, z)
            built.pose.orientation.w = 1.0
            return built

        two = (origin, origin)
        self.frame = marker(('frame', 0), Marker.LINE_LIST, _colour('frame_grey'), line, (
            (0.0, 0.0), (0.0, -h), (-guide, ram_y + rail), (guide, ram_y + rail),
            (-guide, ram_y - rail), (guide, ram_y - rail)))
        self.flywheel = marker(('flywheel', 0), Marker.CYLINDER, _colour('flywheel_blue', 0.5),
                               (2 * sizes.flywheel_radius, 2 * sizes.flywheel_radius, width),
                               z=-width)
        self.slot = marker(('coupling_slot', 0), Marker.LINE_LIST, _colour('slot_black'),
                           (0.6 * width, 0.0, 0.0), two)
        # One LINE_LIST with a colour per point: every marker costs rclpy about 12 us to
        # convert, a point under 1 (the moving part is sent at marker_rate beside the ticks).
        self.links = marker(('links', 0), Marker.LINE_LIST, _colour('lever_green'), line,
                            two * len(LINK_BARS))
        self.links.colors = [_colour(colour) for _, colour in LINK_BARS for _ in two]
        self.ram = marker(('ram', 0), Marker.CUBE, _colour('ram_red'),
                          (sizes.ram_length, sizes.ram_thickness, width))
        self.pins = marker(('pins', 0), Marker.SPHERE_LIST, _colour('pin_black'), pin,
                           (origin,) * 3)
        self.pivots = marker(('pivots', 0), Marker.SPHERE_LIST, _colour('frame_grey'), pin,
                             (origin,) * 3)
        self.workpiece = marker(('workpiece', 0), Marker.CUBE, _colour('workpiece_brown', 0.8),
                                (width, sizes.ram_thickness, width), z=-width)
        self.no_workpiece = Marker(header=header, ns='workpiece', id=0, action=Marker.DELETE)
        self.workpiece_length = None
        text_height = 0.08 * geometry.ram_height
        self.label = marker(('label', 0), Marker.TEXT_VIEW_FACING,
                            ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0), (0.0, 0.0, text_height),
                            position=(0.0, ram_y + sizes.ram_thickness + 2 * text_height))
        self.array = MarkerArray(markers=[
            self.frame, self.flywheel, self.slot, self.links, self.ram, self.pins, self.pivots,
            self.no_workpiece, self.label])
        self.moving = MarkerArray(markers=[self.slot, self.links, self.ram, self.pins])

    def show_workpiece(self, geometry, cutting_length):
        if cutting_length != self.workpiece_length:
            low, high = workpiece_span(geometry, cutting_length, self.sizes)
            self.workpiece.scale.x = high - low
            top = self.sizes.ram_line_height - self.sizes.tool_drop
            _set(self.workpiece.pose.position,
                 (0.5 * (low + high), top - 0.5 * self.sizes.ram_thickness))
            self.workpiece_length = cutting_length
        self.array.markers[_WORKPIECE] = self.workpiece


_WORKPIECE = MARKER_KEYS.index(('workpiece', 0))


@functools.lru_cache(maxsize=8)
def _markers(geometry):
    return _Markers(geometry)


@functools.lru_cache(maxsize=256)
def _ratios(geometry, offset, direction):
    return (kin.time_ratio(geometry, offset, direction),
            kin.speed_ratio(geometry, offset, direction))


def label_text(offset, time_ratio, speed_ratio, stroke=None):
    """Return the label's text: the offset and stroke (m) in force, the theory ratios there."""
    text = f'offset {offset * 1e3:+.2f} mm\nTR {time_ratio:.4f}  SR {speed_ratio:.4f}'
    return text if stroke is None else f'{text}\nstroke {stroke * 1e3:.2f} mm'


def linkage_marker_array(geometry, offset, input_angle, stamp, frame_id, *, input_speed=1.0,
                         mechanism_state=None, loads=None, moving_only=False):
    """
    Return the MarkerArray of the mechanism at one state.

    geometry: ``kinematics.Geometry`` (the markers are built once per geometry object, so
    keep passing the same one); offset (m, in force) and input_angle (rad): the state;
    stamp: ``builtin_interfaces/Time`` or integer nanoseconds; frame_id: the node's;
    input_speed (rad/s): only its sign is used, for the direction of the TR and SR in the
    label (0 counts as forward); mechanism_state: ``kinematics.state`` at this offset and
    angle if the caller has it (saves recomputing it); loads: an object with
    ``cutting_force`` (N) and ``cutting_length`` (m), as ``qrm_ros.core.dynamics.Loads``: the
    workpiece span is drawn while both are > 0. moving_only: only the MOVING_KEYS markers
    (send the whole array whenever the offset, the direction, the loads or the frame change).

    The array and its markers are reused by the next call for the same geometry (as the
    node reuses its JointState): publish it, or copy what you keep.
    """
    built = _markers(geometry)
    offset = float(offset)
    points = linkage_points(geometry, offset, input_angle, mechanism_state, built.sizes)
    built.header.stamp = stamp_message(stamp)
    built.header.frame_id = frame_id
    _set(built.slot.points[1], points.slot_end)
    tool_root = (points.ram_block[0] - 0.5 * built.sizes.ram_length, points.ram_block[1])
    for target, source in zip(built.links.points, (
            points.input_centre, points.coupling_pin,  # in LINK_BARS' order
            points.flywheel_centre, points.crank_pin,
            points.lever_pivot, points.lever_tip,
            tool_root, points.tool_tip)):
        _set(target, source)
    _set(built.ram.pose.position, points.ram_block)
    for target, source in zip(built.pins.points, (points.coupling_pin, points.crank_pin,
                                                  points.ram_block)):
        _set(target, source)
    for target, source in zip(built.pivots.points, (points.input_centre,
                                                    points.flywheel_centre,
                                                    points.lever_pivot)):
        _set(target, source)
    if (loads is not None and float(loads.cutting_force) > 0.0
            and float(loads.cutting_length) > 0.0):
        built.show_workpiece(geometry, float(loads.cutting_length))
    else:
        built.array.markers[_WORKPIECE] = built.no_workpiece
    direction = -1.0 if input_speed < 0.0 else 1.0
    built.label.text = label_text(offset, *_ratios(geometry, offset, direction),
                                  built.stroke)
    return built.moving if moving_only else built.array


def delete_all_marker_array(stamp=0, frame_id=''):
    """Return a MarkerArray that clears every marker (send it on reset, before new ones)."""
    header = Header(stamp=stamp_message(stamp), frame_id=frame_id)
    return MarkerArray(markers=[Marker(header=header, action=Marker.DELETEALL)])
