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
The checks of a run's decoded joint states, block by block, and the list of what was lost.

A block is checked against the last sample of the block before it (repeated stamps span
blocks), so the same checks serve a run read whole and a run streamed through in bounded
memory, with the same result: non-finite motion is excluded, non-finite efforts are
dropped (the motion kept), an exact repeat of the previous message counts once and a
conflicting one is excluded, and every exclusion is counted by reason with its log-time span.
"""

from typing import Dict, List, NamedTuple, Optional, Tuple

import numpy as np

from qrm_ros.analysis.joint_state_decoding import DecodedBlock, JOINT_STATES_TOPIC
from qrm_ros.analysis.sample_consistency import contradicted
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.bag_reader import Loss, Run

# The loss stages: not read from the file at all, read but not usable as a sample, or used
# as a sample without its efforts (the motion kept).
IN_FILE, IN_MESSAGE, IN_EFFORTS = 'file', 'message', 'efforts'
NON_FINITE_MOTION = 'non-finite positions or velocities'
CONFLICTING_STAMP = 'the stamp of the previous message with other values'


class Lost(NamedTuple):
    """Joint-state messages left out of the analysis, and why (times: s of log time)."""

    stage: str  # IN_FILE: never read; IN_MESSAGE: read but not usable; IN_EFFORTS: see above
    reason: str
    messages: Optional[int]  # None: unknown
    start_time: Optional[float]  # from the recording's first message; None: unknown
    end_time: Optional[float]


class CheckedBlock(NamedTuple):
    """The usable samples of a block: stamps (ns) and joint arrays in JOINT_NAMES order."""

    stamps: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    efforts: np.ndarray  # NaN rows: no (usable) efforts
    crank_radius: Optional[np.ndarray] = None  # the crank radius joint (NaN: not recorded)
    crank_radius_rate: Optional[np.ndarray] = None


def merge_counts(counts: Dict[str, List[int]], reason: str, count: int, first: int,
                 last: int) -> None:
    """Add count messages logged from first to last (ns) to counts[reason]."""
    entry = counts.setdefault(reason, [0, first, last])
    entry[:] = [entry[0] + count, min(entry[1], first), max(entry[2], last)]


def _merge_times(counts: Dict[str, List[int]], reason: str, log_times: np.ndarray) -> None:
    merge_counts(counts, reason, int(log_times.size), int(log_times.min()),
                 int(log_times.max()))


def seconds_after(log_time: Optional[int], start: Optional[int]) -> Optional[float]:
    """Return a log time (ns) as s after start; None if either is unknown."""
    if log_time is None or start is None:
        return None
    return (log_time - start) / NANOSECONDS_PER_SECOND


class SampleChecks:
    """The checks of a run's joint states, fed its decoded blocks in file order."""

    def __init__(self, geometry: Optional[Geometry] = None) -> None:
        # With a geometry, each sample is also judged by the closed form (sample_consistency).
        self.geometry = geometry
        self.inconsistent = 0  # samples the closed form contradicts
        self.read = 0  # messages read from the file
        self.used = 0  # samples kept
        self.repeated = 0  # exact repeats of the previous message, counted once
        self.rejected: Dict[str, List[int]] = {}  # reason -> [count, first, last log time]
        self.file_losses: List[Loss] = []  # what the reader could not read
        self.last_log_time: Optional[int] = None  # of the last message decoded
        self._efforts_lost: Dict[str, List[int]] = {}
        self._previous: Optional[Tuple[np.ndarray, ...]] = None  # the last finite sample

    def check(self, block: DecodedBlock) -> CheckedBlock:
        """Check a block; return its usable samples, with unusable efforts as NaN."""
        self.read += block.read
        log_times = block.log_times
        if log_times.size:
            last = int(log_times.max())
            self.last_log_time = last if self.last_log_time is None else max(
                self.last_log_time, last)
        position, velocity = block.positions, block.velocities
        finite = np.isfinite(position).all(axis=1) & np.isfinite(velocity).all(axis=1)
        if not finite.all():
            _merge_times(self.rejected, NON_FINITE_MOTION, log_times[~finite])
        count = block.stamps.size
        if self.geometry is not None:
            # Each sample is judged with the crank radius in force (its recorded one, when
            # the recording has the crank radius joint: a stroke changed mid-run included).
            for reason, caught in contradicted(self.geometry, position, velocity, finite,
                                               block.crank_radius, block.crank_radius_rate):
                self.inconsistent += int(caught.sum())
                _merge_times(self.rejected, reason, log_times[caught])
                finite &= ~caught
        radius = (np.full(count, np.nan) if block.crank_radius is None
                  else block.crank_radius)[finite]
        radius_rate = (np.full(count, np.nan) if block.crank_radius_rate is None
                       else block.crank_radius_rate)[finite]
        stamps, log_times = block.stamps[finite], log_times[finite]
        position, velocity, effort = position[finite], velocity[finite], block.efforts[finite]
        # A recorded effort that is not finite is not a measurement: the sample keeps its
        # motion, its efforts count as not recorded (NaN), and how many is listed.
        recorded = ~np.isnan(effort).all(axis=1)
        unusable = recorded & ~np.isfinite(effort).all(axis=1)
        if unusable.any():
            effort[unusable] = np.nan
            _merge_times(self._efforts_lost, IN_EFFORTS, log_times[unusable])
        if not stamps.size:
            return CheckedBlock(stamps, position, velocity, effort, radius, radius_rate)
        # The same stamp as the previous message: an exact repeat counts once; a conflicting
        # one is excluded (which of the two is right cannot be told).
        carried = self._previous is not None
        every: Tuple[np.ndarray, ...] = (stamps, position, velocity, effort)
        if self._previous is not None:
            every = tuple(np.concatenate([before, now]) for before, now in
                          zip(self._previous, every))
        all_stamps, all_position, all_velocity, all_effort = every
        repeat = np.zeros(all_stamps.size, dtype=bool)
        repeat[1:] = np.diff(all_stamps) == 0
        same = np.zeros_like(repeat)
        same[1:] = ((all_position[1:] == all_position[:-1]).all(axis=1)
                    & (all_velocity[1:] == all_velocity[:-1]).all(axis=1)
                    & ((all_effort[1:] == all_effort[:-1])
                       | (np.isnan(all_effort[1:]) & np.isnan(all_effort[:-1]))).all(axis=1))
        if carried:
            repeat, same = repeat[1:], same[1:]
        self._previous = (stamps[-1:], position[-1:], velocity[-1:], effort[-1:])
        conflicting = repeat & ~same
        if conflicting.any():
            _merge_times(self.rejected, CONFLICTING_STAMP, log_times[conflicting])
        self.repeated += int((repeat & same).sum())
        keep = ~repeat
        self.used += int(keep.sum())
        return CheckedBlock(stamps[keep], position[keep], velocity[keep], effort[keep],
                            radius[keep], radius_rate[keep])

    def messages_in_file(self, run: Run) -> Optional[int]:
        """Return the file's own count of joint-state messages; None: unknown."""
        return run.message_count(JOINT_STATES_TOPIC) if run.counted else None

    def losses(self, run: Run) -> List[Lost]:
        """Return everything left out, once every block was checked."""
        start = run.start_time
        losses = [Lost(IN_FILE, loss.reason, loss.messages,
                       seconds_after(loss.start_time, start), seconds_after(loss.end_time, start))
                  for loss in self.file_losses]
        in_file = self.messages_in_file(run)
        if in_file is not None:
            # The statistics count every message written: the exact toll of the damage,
            # whatever the damaged chunks' own message indexes said.
            unread = in_file - self.read - sum(loss.messages or 0 for loss in losses)
            if unread or any(loss.messages is None for loss in losses):
                losses.append(Lost(IN_FILE, f'in all, {in_file - self.read} of the {in_file} '
                                   'messages the file counts could not be read', unread, None,
                                   None))
        if not run.data_complete:
            losses.append(Lost(IN_FILE, 'messages after the last whole record (how many is '
                               'unknown)', None, seconds_after(self.last_log_time, start), None))
        for count, first, last in self._efforts_lost.values():
            losses.append(Lost(IN_EFFORTS, 'non-finite efforts (the motion kept)', count,
                               seconds_after(first, start), seconds_after(last, start)))
        for reason, (count, first, last) in sorted(self.rejected.items()):
            losses.append(Lost(IN_MESSAGE, reason, count, seconds_after(first, start),
                               seconds_after(last, start)))
        return losses
