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
When the shaper_sim node sends its linkage markers, and how much of them.

Right after a tick, at marker_rate: the whole array when what the still markers show changes
and at least every MARKER_REFRESH_PERIOD, the moving markers alone in between; above a
publish rate of MARKER_SLICING_RATE a frame goes out one marker a tick. The markers
themselves are drawn by qrm_ros.node.shaper_sim.linkage_markers.
"""

import time
from typing import Callable, List, NamedTuple, Optional

from qrm_ros.core.dynamics.chain import Loads
from qrm_ros.core.kinematics.geometry import Geometry, MechanismState
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.node.shaper_sim.linkage_markers import delete_all_marker_array, linkage_marker_array
from qrm_ros.node.shaper_sim.shaper_parameters import MARKER_SLICING_RATE
from rclpy.publisher import Publisher
from visualization_msgs.msg import MarkerArray

__all__ = ['LinkageMarkerSchedule', 'MARKER_REFRESH_PERIOD', 'MARKER_SLICING_RATE',
           'MarkerScene']

# s: the whole marker array is sent at least this often (a viewer started later sees the
# still parts within it), the moving markers alone in between.
MARKER_REFRESH_PERIOD = 1.0


class MarkerScene(NamedTuple):
    """What a frame draws: the latest published sample and how it is shown."""

    stamp_ns: int
    offset: float  # m
    input_angle: float  # rad
    input_speed: float  # rad/s
    frame_id: str
    loads: Loads
    geometry: Optional[Geometry] = None  # with the crank radius in force (None: the schedule's)


class LinkageMarkerSchedule:
    """Sends the linkage markers after the ticks at their rate; see the module docstring."""

    def __init__(self, publisher: Publisher, geometry: Geometry, publish_rate: float,
                 scene: Callable[[], Optional[MarkerScene]]):
        """scene: what to draw now (None before the first published sample)."""
        self._publisher = publisher
        self._geometry = geometry
        self._scene = scene
        self._period_ns = 0
        self._next_ns = 0
        # A frame's markers still to publish, one a tick (above MARKER_SLICING_RATE).
        self._slices: List[MarkerArray] = []
        self._slice_frames = publish_rate > MARKER_SLICING_RATE
        self._clear = False
        # What the still markers last sent show (offset, reversed, frame, loads), and when (s).
        self._still: Optional[tuple] = None
        self._still_sent = 0.0

    def set_rate(self, rate: float) -> None:
        """
        Publish the markers at rate Hz (0: stop), each right after a tick.

        Not on a timer of their own: one firing just before a tick was due made the tick
        late by the markers' conversion (up to 0.75 ms in a running node); right after a
        tick they use the time to the next one. Each frame is built within one tick period of
        when it is due (so at most once per tick); above MARKER_SLICING_RATE its markers then
        go out one a tick, and the next frame waits for them (at 4 kHz, a moving frame's four
        markers take 1.25 ms of a 33 ms period at 30 Hz).
        """
        self._period_ns = round(NANOSECONDS_PER_SECOND / rate) if rate > 0.0 else 0
        self._next_ns = 0

    def clear(self) -> None:
        """Send a DELETEALL before the next frame and drop the rest of one under way."""
        self._clear = True
        self._slices = []

    def publish_if_due(self, stamp_ns: int, sample: Optional[MechanismState] = None) -> None:
        """
        After a tick at stamp_ns (node clock): send what is due.

        sample: the core's state at the stepper's present one, if known.
        """
        if self._slices:  # a frame under way: its next marker, the next frame waits
            self._publisher.publish(self._slices.pop())
            return
        period, due = self._period_ns, self._next_ns
        if period and (stamp_ns >= due or stamp_ns < due - period):  # due, or time went back
            # The next a period after this one's due time (the rate kept on average), or
            # after now when the first, a period behind or after the clock went back.
            late = stamp_ns - due
            self._next_ns = (due if 0 <= late < period else stamp_ns) + period
            if self._slice_frames:  # built now, sent from the next tick on
                frame = self._frame(sample)
                self._slices = [
                    MarkerArray(markers=[marker]) for markers in reversed(frame or ())
                    for marker in reversed(markers.markers)]
            else:
                self.publish_frame(sample)

    def publish_frame(self, sample: Optional[MechanismState] = None) -> bool:
        """
        Publish the mechanism as markers at the latest published sample (its stamp), now.

        Returns False before the first sample. After a reset a DELETEALL goes first, so no
        stale part is left behind. The workpiece is drawn while there is a cutting load. The
        whole array goes out when what the still markers show changes (offset, direction,
        frame, loads) and at least every MARKER_REFRESH_PERIOD (for a viewer that starts
        later); in between only the moving markers, which keeps the conversion's hold on the
        GIL off the ticks (see linkage_markers). Above MARKER_SLICING_RATE the timer sends the
        same frame one marker per tick instead (what this one supersedes is dropped).
        """
        self._slices = []
        frame = self._frame(sample)
        for markers in frame or ():
            self._publisher.publish(markers)
        return frame is not None

    def _frame(self, sample: Optional[MechanismState] = None) -> Optional[List[MarkerArray]]:
        """Return the MarkerArrays of the latest published sample, in order (None: none)."""
        scene = self._scene()
        if scene is None:
            return None
        frame = []
        if self._clear:
            frame.append(delete_all_marker_array(scene.stamp_ns, scene.frame_id))
            self._clear = False
            self._still = None
        geometry = scene.geometry or self._geometry
        still = (scene.offset, scene.input_speed < 0.0, scene.frame_id, scene.loads,
                 geometry.crank_radius)
        now = time.monotonic()
        moving_only = (still == self._still
                       and now - self._still_sent < MARKER_REFRESH_PERIOD)
        if not moving_only:
            self._still, self._still_sent = still, now
        frame.append(linkage_marker_array(
            geometry, scene.offset, scene.input_angle, scene.stamp_ns, scene.frame_id,
            input_speed=scene.input_speed, mechanism_state=sample, loads=scene.loads,
            moving_only=moving_only))
        return frame
