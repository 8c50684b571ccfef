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
The linkage markers: the pins where the core puts them, stable keys, the workpiece with a
cutting load, the label's ratios (against the paper's own ways), and a trip over real DDS.
"""

from collections import namedtuple
import math

from builtin_interfaces.msg import Time
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import QoSProfile
from visualization_msgs.msg import Marker, MarkerArray

from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.linkage import COLOURS, linkage_sizes, workpiece_span
from qrm_ros.node.shaper_sim.linkage_markers import (delete_all_marker_array, LINK_BARS,
                                                     linkage_marker_array, MARKER_KEYS,
                                                     MOVING_KEYS)
from qrm_ros.core.common.names import LINKAGE_MARKERS_TOPIC
from ros_probe import BackgroundSpinner, wait_for

Loads = namedtuple('Loads', 'cutting_force ram_friction cutting_length')
GEOMETRY = kin.Geometry.paper()


def _by_key(array):
    return {(m.ns, m.id): m for m in array.markers}


def _xy(point):
    return (point.x, point.y)


def _bars(links):
    """Return the links marker's bars: name -> (start, end), each bar in its own colour."""
    assert links.type == Marker.LINE_LIST
    assert len(links.points) == len(links.colors) == 2 * len(LINK_BARS)
    bars = {}
    for index, (name, colour) in enumerate(LINK_BARS):
        for corner in links.colors[2 * index:2 * index + 2]:
            assert (corner.r, corner.g, corner.b, corner.a) == pytest.approx(COLOURS[colour])
        bars[name] = tuple(_xy(p) for p in links.points[2 * index:2 * index + 2])
    return bars


def _core_pins(geometry, offset, input_angle):
    """Pins straight from doc/mechanism.md with the core's joint values."""
    state = kin.state(geometry, offset, input_angle, 1.0)
    crank = state.flywheel_angle + geometry.crank_phase
    return {
        'coupling_pin': (geometry.coupling_radius * math.cos(input_angle),
                         offset + geometry.coupling_radius * math.sin(input_angle)),
        'crank_pin': (geometry.crank_radius * math.cos(crank),
                      geometry.crank_radius * math.sin(crank)),
        'ram_block': (state.ram_position, geometry.ram_height - geometry.pivot_distance),
    }


@pytest.mark.parametrize('geometry', [
    GEOMETRY, kin.Geometry(0.03, 0.07, 0.16, ram_height=0.35, crank_phase=0.4)])
def test_marker_pins_are_the_cores_pins(geometry):
    rng = np.random.default_rng(11)
    for input_angle, offset in zip(rng.uniform(-10, 10, 200),
                                   rng.uniform(-0.9, 0.9, 200) * geometry.coupling_radius):
        markers = _by_key(linkage_marker_array(geometry, offset, input_angle, 0, 'base'))
        pins = _core_pins(geometry, offset, input_angle)
        drawn = markers['pins', 0].points
        for point, name in zip(drawn, ('coupling_pin', 'crank_pin', 'ram_block')):
            assert _xy(point) == pytest.approx(pins[name], abs=1e-15)
            assert point.z == 0.0
        # The links end on the pins and pivots.
        bars = _bars(markers['links', 0])
        assert bars['input_crank'] == ((0.0, offset), _xy(drawn[0]))
        assert bars['crank'] == ((0.0, 0.0), _xy(drawn[1]))
        assert _xy(markers['ram', 0].pose.position) == _xy(drawn[2])
        assert bars['lever'][0] == (0.0, -geometry.pivot_distance)
        # The lever's tip is on the line from its pivot through the crank pin.
        (pivot_x, pivot_y), (tip_x, tip_y) = bars['lever']
        assert (tip_x - pivot_x) * (drawn[1].y - pivot_y) == pytest.approx(
            (tip_y - pivot_y) * (drawn[1].x - pivot_x), abs=1e-15)
        # The tool hangs from the ram block's rear end.
        sizes = linkage_sizes(geometry)
        assert bars['tool'][0] == (drawn[2].x - 0.5 * sizes.ram_length, drawn[2].y)
        assert [_xy(p) for p in markers['pivots', 0].points] == [
            (0.0, offset), (0.0, 0.0), (0.0, -geometry.pivot_distance)]


def test_the_moving_markers_alone_are_those_that_move_at_a_fixed_offset():
    """moving_only leaves out exactly the markers that stay put while the shaft turns."""
    assert set(MOVING_KEYS) < set(MARKER_KEYS)
    assert list(MOVING_KEYS) == [key for key in MARKER_KEYS if key in MOVING_KEYS]

    def copied(array):  # the calls reuse their markers: keep copies
        return {(m.ns, m.id): (m.action, [_xy(p) for p in m.points], m.pose.position.x,
                               m.pose.position.y, m.text, m.header.stamp.sec)
                for m in array.markers}
    angles = (0.3, 1.9, 4.4)
    whole = [copied(linkage_marker_array(GEOMETRY, 0.012, angle, index * 10**9, 'f'))
             for index, angle in enumerate(angles)]
    moving = [copied(linkage_marker_array(GEOMETRY, 0.012, angle, index * 10**9, 'f',
                                          moving_only=True))
              for index, angle in enumerate(angles)]
    for full, part in zip(whole, moving):
        assert list(part) == list(MOVING_KEYS)
        assert all(part[key] == full[key] for key in MOVING_KEYS)
    for key in MARKER_KEYS:
        changed = any(whole[0][key][:5] != other[key][:5] for other in whole[1:])
        assert changed == (key in MOVING_KEYS), key


def test_a_state_with_speeds_draws_the_same_points_as_none():
    """The node hands over its published sample (kinematics.state with its rates): same bits."""
    rng = np.random.default_rng(3)

    def points(**state):
        array = linkage_marker_array(GEOMETRY, offset, angle, 0, 'f', **state)
        return [(m.pose.position.x, m.pose.position.y, [_xy(p) for p in m.points])
                for m in array.markers]
    for _ in range(200):
        offset = float(rng.uniform(-0.02, 0.02))
        angle = float(rng.uniform(-math.pi, math.pi))
        sample = kin.state(GEOMETRY, offset, angle, float(rng.uniform(-50.0, 50.0)),
                           float(rng.uniform(-9.0, 9.0)), float(rng.uniform(-0.01, 0.01)))
        assert points(mechanism_state=sample) == points()


def test_keys_header_and_well_formed_markers():
    stamp = 1_234_567_891_011
    first = linkage_marker_array(GEOMETRY, 0.0, 0.5, stamp, 'shaper_base')
    keys = [(m.ns, m.id) for m in first.markers]
    assert keys == list(MARKER_KEYS) and len(set(keys)) == len(keys)
    second = linkage_marker_array(GEOMETRY, 0.01, 2.5, Time(sec=7, nanosec=8), 'other')
    assert [(m.ns, m.id) for m in second.markers] == keys
    for marker in second.markers:
        assert marker.header.frame_id == 'other'
        assert (marker.header.stamp.sec, marker.header.stamp.nanosec) == (7, 8)
        if marker.action != Marker.ADD:
            continue
        assert marker.color.a > 0.0
        assert marker.pose.orientation.w == 1.0
        values = [marker.scale.x, marker.scale.y, marker.scale.z, marker.pose.position.x,
                  marker.pose.position.y] + [c for p in marker.points for c in (p.x, p.y, p.z)]
        assert all(math.isfinite(v) for v in values)
    stamp_of = linkage_marker_array(GEOMETRY, 0.0, 0.5, stamp, 'f').markers[0].header.stamp
    assert (stamp_of.sec, stamp_of.nanosec) == (1234, 567_891_011)


def test_workpiece_only_with_a_cutting_load():
    without = _by_key(linkage_marker_array(GEOMETRY, 0.0, 0.0, 0, 'f'))
    assert without['workpiece', 0].action == Marker.DELETE
    idle = Loads(cutting_force=0.0, ram_friction=5.0, cutting_length=0.1)
    assert _by_key(linkage_marker_array(GEOMETRY, 0.0, 0.0, 0, 'f', loads=idle))[
        'workpiece', 0].action == Marker.DELETE
    for length in (0.1, 0.15):
        loads = Loads(cutting_force=500.0, ram_friction=0.0, cutting_length=length)
        piece = _by_key(linkage_marker_array(GEOMETRY, 0.0, 0.0, 0, 'f', loads=loads))[
            'workpiece', 0]
        assert piece.action == Marker.ADD and piece.type == Marker.CUBE
        low, high = workpiece_span(GEOMETRY, length)
        centre, half = piece.pose.position.x, 0.5 * piece.scale.x
        assert (centre - half, centre + half) == pytest.approx((low, high), abs=1e-15)
        sizes = linkage_sizes(GEOMETRY)
        top = piece.pose.position.y + 0.5 * piece.scale.y
        assert top == pytest.approx(sizes.ram_line_height - sizes.tool_drop, abs=1e-15)
    assert _by_key(linkage_marker_array(GEOMETRY, 0.0, 0.0, 0, 'f'))[
        'workpiece', 0].action == Marker.DELETE


@pytest.mark.parametrize('offset', [-0.015, -0.0111725663716814, 0.0, 0.01])
def test_label_shows_offset_and_the_ratios(offset):
    label = _by_key(linkage_marker_array(GEOMETRY, offset, 0.0, 0, 'f'))['label', 0]
    assert label.type == Marker.TEXT_VIEW_FACING
    first, second, third = label.text.split('\n')
    assert first == f'offset {offset * 1e3:+.2f} mm'
    # The stroke in force, 2 H r / sqrt(h^2 - r^2) written out (doc/mechanism.md).
    r, h, height = GEOMETRY.crank_radius, GEOMETRY.pivot_distance, GEOMETRY.ram_height
    assert third == f'stroke {2e3 * height * r / math.sqrt(h * h - r * r):.2f} mm'
    words = second.split()
    # Against the paper's ways: RK4 of eq. (20) for TR, eq. (25) for SR.
    assert words[0] == 'TR' and words[1] == f'{kin.time_ratio_rk4(GEOMETRY, offset):.4f}'
    assert words[2] == 'SR' and words[3] == f'{kin.speed_ratio_eq25(GEOMETRY, offset):.4f}'
    backward = _by_key(linkage_marker_array(GEOMETRY, offset, 0.0, 0, 'f', input_speed=-3.0))[
        'label', 0].text.split()
    assert float(backward[4]) == pytest.approx(1 / float(words[1]), rel=2e-4)
    assert float(backward[6]) == pytest.approx(1 / float(words[3]), rel=2e-4)


def test_delete_all_clears_everything():
    array = delete_all_marker_array(5_000_000_000, 'shaper_base')
    assert len(array.markers) == 1
    marker = array.markers[0]
    assert marker.action == Marker.DELETEALL and marker.ns == ''
    assert marker.header.stamp.sec == 5 and marker.header.frame_id == 'shaper_base'


def test_markers_cross_real_dds_intact():
    context = Context()
    rclpy.init(context=context)
    try:
        publisher_node = Node('marker_source', context=context)
        probe = Node('marker_probe', context=context)
        received = []
        probe.create_subscription(MarkerArray, LINKAGE_MARKERS_TOPIC, received.append,
                                  QoSProfile(depth=10))
        publisher = publisher_node.create_publisher(MarkerArray, LINKAGE_MARKERS_TOPIC, 10)
        spinner = BackgroundSpinner(context, probe)
        try:
            wait_for(lambda: publisher.get_subscription_count() > 0, what='the probe')
            loads = Loads(cutting_force=100.0, ram_friction=0.0, cutting_length=0.1)
            publisher.publish(linkage_marker_array(GEOMETRY, 0.012, 1.3, 42, 'shaper_base',
                                                   loads=loads))
            publisher.publish(delete_all_marker_array(43, 'shaper_base'))
            wait_for(lambda: len(received) == 2, what='two marker arrays')
        finally:
            spinner.stop()
        markers = _by_key(received[0])
        assert [(m.ns, m.id) for m in received[0].markers] == list(MARKER_KEYS)
        pins = _core_pins(GEOMETRY, 0.012, 1.3)
        for point, name in zip(markers['pins', 0].points,
                               ('coupling_pin', 'crank_pin', 'ram_block')):
            assert _xy(point) == pytest.approx(pins[name], abs=1e-15)
        assert markers['workpiece', 0].action == Marker.ADD
        assert 'TR' in markers['label', 0].text
        assert received[1].markers[0].action == Marker.DELETEALL
    finally:
        rclpy.shutdown(context=context)
