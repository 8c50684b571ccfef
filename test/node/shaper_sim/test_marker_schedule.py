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
The shaper_sim node's linkage markers (qrm_ros.node.shaper_sim.marker_schedule), in-process.

What the markers show, when they go out (after the ticks, at their rate, whole or the moving
part, one marker a tick above MARKER_SLICING_RATE), over real rclpy and DDS.
"""

import itertools
import math
import time

import pytest
from qrm_ros.node.shaper_sim import marker_schedule
from qrm_ros.node.shaper_sim.linkage_markers import linkage_marker_array, MARKER_KEYS, MOVING_KEYS
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from ros_probe import stamp_ns
from shaper_harness import H_PIVOT, NS, R, R1, run_ticks


def test_markers_show_the_published_state_and_clear_on_reset(harness):
    h = harness(spin_shaper=False, coupling_offset=0.012, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    assert not h.shaper.publish_markers()  # nothing published yet: nothing to draw
    run_ticks(h.shaper, 50 * NS, 0.37)
    assert h.shaper.publish_markers()
    h.wait_for(lambda: arrays and len(h.joint_states) >= 37, what='markers and joint states')
    joint_state = h.joint_states[-1]
    markers = {(m.ns, m.id): m for m in arrays[-1].markers}
    assert all(m.header.stamp == joint_state.header.stamp for m in markers.values())
    # The pins, from the published joint values by the mechanism's own definitions
    # (mechanism.md): coupling pin on the input crank at r1 about O1 = (0, offset); crank pin
    # on the flywheel at r, at the crank phase; ram block on the ram line, H above O3.
    angle, flywheel, lever, ram, offset, radius = joint_state.position
    assert radius == R  # the crank pin at the published crank radius
    expected = [(R1 * math.cos(angle), offset + R1 * math.sin(angle)),
                (radius * math.cos(flywheel), radius * math.sin(flywheel)),
                (0.2 * math.tan(lever), -H_PIVOT + 0.2)]
    pins = markers['pins', 0].points
    for point, (x, y) in zip(pins, expected):
        assert (point.x, point.y) == pytest.approx((x, y), abs=1e-12)
    assert pins[2].x == pytest.approx(ram, abs=1e-15)
    assert 'offset +12.00 mm' in markers['label', 0].text
    # The service's callback, called as the executor would (this node is not spun here).
    assert h.shaper.on_reset(Trigger.Request(), Trigger.Response()).success
    count = len(arrays)
    run_ticks(h.shaper, 60 * NS, 0.05)
    assert h.shaper.publish_markers()
    h.wait_for(lambda: len(arrays) >= count + 2, what='markers after the reset')
    assert [m.action for m in arrays[count].markers] == [Marker.DELETEALL]
    assert len(arrays[count + 1].markers) > 5


def test_still_markers_go_out_when_they_change_and_every_refresh_period(harness, monkeypatch):
    h = harness(spin_shaper=False, coupling_offset=0.012, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    stamp = [50 * NS]

    def publish(count=1):
        for _ in range(count):
            stamp[0] = run_ticks(h.shaper, stamp[0], 0.02)[-1]
            assert h.shaper.publish_markers()
        h.wait_for(lambda: len(arrays) >= sent + count, what='markers')
        return [len(array.markers) for array in arrays[sent:sent + count]]

    sent = 0
    assert publish(3) == [len(MARKER_KEYS), len(MOVING_KEYS), len(MOVING_KEYS)]
    sent = len(arrays)
    h.shaper.stepper.set_offset_command(0.0)  # the offset jumps: pivots and label change
    h.shaper.stepper.set_limits(offset_rate_limit=1e9)
    assert publish(2) == [len(MARKER_KEYS), len(MOVING_KEYS)]
    sent = len(arrays)
    monkeypatch.setattr(marker_schedule, 'MARKER_REFRESH_PERIOD', 0.0)  # a late viewer's refresh
    assert publish(2) == [len(MARKER_KEYS), len(MARKER_KEYS)]


def test_markers_follow_ticks_at_their_rate_and_survive_the_clock_going_back(harness):
    h = harness(spin_shaper=False, marker_rate=30.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 1000)
    stamps = run_ticks(h.shaper, 50 * NS, 2.0, rate=1000.0, jitter_ns=100_000)
    h.wait_for(lambda: len(arrays) >= 60, what='two seconds of markers')
    marker_stamps = [stamp_ns(array.markers[0]) for array in arrays]
    assert set(marker_stamps) <= set(stamps)  # each drawn at a published sample
    # 30 Hz on average, each within a tick period (1 ms, jitter 0.1 ms) of its due time.
    assert len(marker_stamps) == 60
    for index, stamp in enumerate(marker_stamps):
        assert 0 <= stamp - (marker_stamps[0] + index * NS / 30) < 1.2e6
    run_ticks(h.shaper, 10 * NS, 0.2, rate=1000.0, jitter_ns=100_000)  # sim time restarted
    h.wait_for(lambda: len(arrays) >= 66, what='markers going on after the clock went back')


def test_above_the_slicing_rate_a_frame_goes_out_one_marker_a_tick(harness):
    """The same frames as in one array, each marker in a tick of its own after the build."""
    rate = 2 * marker_schedule.MARKER_SLICING_RATE
    h = harness(spin_shaper=False, publish_rate=rate, marker_rate=50.0, coupling_offset=0.012)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 1000)
    stamps = run_ticks(h.shaper, 50 * NS, 0.1, rate=rate, jitter_ns=0)
    h.wait_for(lambda: len(h.joint_states) == len(stamps), what='the joint states')
    assert h.shaper.on_reset(Trigger.Request(), Trigger.Response()).success
    stamps += run_ticks(h.shaper, 60 * NS, 0.02, rate=rate, jitter_ns=0)
    frames = len(MARKER_KEYS) + 4 * len(MOVING_KEYS) + 1 + len(MARKER_KEYS)
    h.wait_for(lambda: len(arrays) >= frames, what='five frames, one marker a message')
    assert all(len(array.markers) == 1 for array in arrays)
    markers = [array.markers[0] for array in arrays]
    # Grouped by the sample they draw: whole, four moving ones, then DELETEALL and whole.
    groups = [(stamp, list(group)) for stamp, group in itertools.groupby(markers, stamp_ns)]
    keys = [[(m.ns, m.id) for m in group if m.action != Marker.DELETEALL]
            for _, group in groups]
    assert keys[:6] == [list(MARKER_KEYS)] + [list(MOVING_KEYS)] * 4 + [list(MARKER_KEYS)]
    assert [m.action for m in groups[5][1]][0] == Marker.DELETEALL
    # Every marker as the unsliced frame at that sample has it (the published input angle).
    states = {stamp_ns(m): m for m in h.joint_states}
    for (stamp, group), moving in zip(groups[:5], [False] + [True] * 4):
        angle = states[stamp].position[0]
        expected = linkage_marker_array(h.shaper.geometry, 0.012, angle, stamp,
                                        h.shaper.get_parameter('frame_id').value,
                                        input_speed=2 * math.pi, loads=h.shaper.loads,
                                        moving_only=moving).markers
        # (as received: the colours' float32 on the wire)
        assert group == [deserialize_message(serialize_message(m), Marker) for m in expected]
    # Each marker a tick after the one before; the frames 1/50 s apart from the first.
    ticks = [stamps.index(stamp) for stamp, _ in groups]
    assert [b - a for a, b in zip(ticks, ticks[1:4])] == [int(rate / 50)] * 3
    # A reset in the middle of a frame drops its rest: the next message is the DELETEALL.
    h.wait_for(lambda: len(arrays) == frames, what='no more markers')
    run_ticks(h.shaper, 70 * NS, 2 / rate, rate=rate, jitter_ns=0)  # a frame, one marker out
    assert h.shaper.on_reset(Trigger.Request(), Trigger.Response()).success
    run_ticks(h.shaper, 71 * NS, 3 / rate, rate=rate, jitter_ns=0)
    h.wait_for(lambda: len(arrays) >= frames + 3, what='a marker, then the next frame')
    assert [m.action for array in arrays[frames:frames + 3] for m in array.markers] == [
        Marker.ADD, Marker.DELETEALL, Marker.ADD]


def test_markers_show_the_workpiece_while_there_is_a_cutting_load(harness):
    h = harness(spin_shaper=False, marker_rate=0.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    run_ticks(h.shaper, 50 * NS, 0.05)
    assert h.shaper.publish_markers()
    assert h.shaper.set_parameters([Parameter('cutting_force', value=400.0),
                                    Parameter('cutting_length', value=0.15)])[0].successful
    run_ticks(h.shaper, 51 * NS, 0.05)
    assert h.shaper.publish_markers()  # the loads changed: the whole array, workpiece drawn
    h.wait_for(lambda: len(arrays) >= 2, what='markers before and after the load')
    before, after = ({(m.ns, m.id): m for m in array.markers} for array in arrays[:2])
    assert before['workpiece', 0].action == Marker.DELETE
    assert after['workpiece', 0].action == Marker.ADD
    # The tool tip's range while cutting: cutting_length long (linkage.workpiece_span).
    assert after['workpiece', 0].scale.x == pytest.approx(0.15, rel=1e-12)


def test_marker_rate_is_live_and_zero_turns_markers_off(harness):
    h = harness(marker_rate=50.0)
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    h.wait_for(lambda: len(arrays) >= 5, what='markers at 50 Hz')
    assert h.shaper.set_parameters([Parameter('marker_rate', value=0.0)])[0].successful
    result, = h.shaper.set_parameters([Parameter('marker_rate', value=-1.0)])
    assert not result.successful and '0 (off) or [0.01, 1000] Hz' in result.reason
    time.sleep(0.1)  # let markers already under way arrive
    count = len(arrays)
    time.sleep(0.3)  # 15 periods at the old rate: none may come
    assert len(arrays) == count
