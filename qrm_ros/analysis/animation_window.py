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
A recorded run animated from the window it shows: memory independent of the run's length.

The measured ratios and what the recording lost come from the streamed analysis
(qrm_ros.analysis.streamed_run.analyse_file); one more pass over the file keeps only the
samples in [start, end] and the last one before start (the first frame may show it). The
frames are those ``animation.write_animation`` draws from the whole run.

The main job's offset tour likewise (``write_window_tour``): one pass keeps the last input
revolution of each segment it shows (``animation.tour_segments``) and, for the time panel, the
whole run's trace thinned to an envelope: in each of ``TRACE_BINS`` runs of consecutive
samples, those of the least and greatest time, ram velocity and input torque. At 800 px that
draws what every sample draws; a run of up to TRACE_BINS samples is drawn whole.
"""

import math
from typing import Iterator, List, NamedTuple, Optional, Set, TextIO, Tuple

import numpy as np

from qrm_ros.analysis.animation import (animate_plan, check_offsets, check_output, check_rates,
                                        frame_plan, largest_crank_radius, render_frames,
                                        segment_at, tour_segments, write_frames)
from qrm_ros.analysis.linkage_figure import LinkageFigure
from qrm_ros.analysis.joint_state_decoding import decoded_blocks, MessageCounter
from qrm_ros.analysis.measurement import Analysis
from qrm_ros.analysis.recorded_run import Samples, samples_of
from qrm_ros.analysis.sample_checks import CheckedBlock, SampleChecks
from qrm_ros.recording.bag_reader import open_run

__all__ = ['RunWindow', 'TRACE_BINS', 'TourWindows', 'TraceEnvelope', 'read_tour',
           'read_window', 'write_window_animation', 'write_window_tour']

# s: the last frame may fall this far past --end (frame times are a float sum).
_END_SLACK = 1e-6


class RunWindow(NamedTuple):
    """The samples of a window of a run, in recording order, and the run's time extent."""

    samples: Samples
    earliest: float  # s, the run's earliest sample
    latest: float  # s, the run's latest sample
    messages_decoded: int  # joint-state messages read to find the window


def _checked_blocks(result: Analysis) -> Iterator[CheckedBlock]:
    recording = result.recording
    checks = SampleChecks(recording.geometry)  # as the analysis checked them
    for block in decoded_blocks(open_run(recording.path), None, checks.file_losses,
                                checks.rejected, MessageCounter()):
        yield checks.check(block)


def read_window(result: Analysis, start: Optional[float], end: Optional[float]) -> RunWindow:
    """
    Read the samples of result's run (analyse_file) with times in [start, end] (s).

    None: from the run's start, to its end. Also the last sample before start: the first
    frame shows the last sample at or before its time.
    """
    low = -math.inf if start is None else float(start)
    high = math.inf if end is None else float(end) + _END_SLACK
    pieces: List[Tuple[int, Samples]] = []
    before: Optional[Tuple[float, int, Samples]] = None
    earliest, latest, count, decoded = math.inf, -math.inf, 0, 0
    for checked in _checked_blocks(result):
        decoded += checked.stamps.size
        if not checked.stamps.size:
            continue
        samples = samples_of(checked, result.recording.time_origin_ns, True)
        time = samples.time
        earliest, latest = min(earliest, float(time.min())), max(latest, float(time.max()))
        kept = np.flatnonzero((time >= low) & (time <= high))
        if kept.size:
            pieces.append((count + int(kept[0]), _taken(samples, kept)))
        earlier = time < low
        if earlier.any():
            last_time = float(time[earlier].max())
            index = int(np.flatnonzero(earlier & (time == last_time))[-1])
            if before is None or last_time >= before[0]:
                before = (last_time, count + index, _taken(samples, np.array([index])))
        count += time.size
    if before is not None:
        pieces.append((before[1], before[2]))
    pieces.sort(key=lambda piece: piece[0])
    return RunWindow(_joined([piece for _, piece in pieces]), earliest, latest, decoded)


def write_window_animation(result: Analysis, path: str, start: Optional[float] = None,
                           end: Optional[float] = None, fps: float = 25.0, speed: float = 1.0,
                           cutting_length: Optional[float] = None,
                           progress_stream: Optional[TextIO] = None) -> int:
    """
    Animate result's run (``streamed_run.analyse_file``) over [start, end] into path.

    The frames of ``animation.write_animation`` with read_window's samples; the input
    torque drawn when every sample shown carries it. Returns the number of frames.
    """
    extension = check_output(path)
    check_rates(fps, speed, extension)
    window = read_window(result, start, end)
    samples = window.samples
    plan = frame_plan(samples.time, start, end, fps, speed, extension,
                      (window.earliest, window.latest))
    check_offsets(result.recording.geometry, samples.offset[plan.sample])
    efforts = samples.input_torque
    if efforts is not None and not np.all(np.isfinite(efforts)):
        efforts = None
    return animate_plan(result.recording.geometry, samples, plan, result, path, fps, efforts,
                        cutting_length, progress_stream)


# Runs of consecutive samples the tour's time panel is thinned to (each gives at most six).
TRACE_BINS = 1000


class TraceEnvelope:
    """
    A whole run's ram velocity and input torque over time, thinned as it streams past.

    Samples are taken in runs of ``bin_size`` consecutive ones; of each run only those of
    the least and greatest time, ram velocity and input torque are kept, in run order.
    """

    def __init__(self, bin_size: int) -> None:
        self.bin_size = max(1, int(bin_size))
        self.kept: List[Tuple[int, float, float, float]] = []  # index, time, velocity, torque
        self._open: List[Tuple[int, float, float, float]] = []  # the last run, not yet whole
        self._open_bin = -1

    def add(self, first_index: int, samples: Samples) -> None:
        """Take in consecutive samples, the first of which is the run's first_index-th."""
        torque = (np.full(samples.time.shape, np.nan) if samples.input_torque is None
                  else samples.input_torque)
        columns = (samples.time, samples.ram_velocity, torque)
        bins = (first_index + np.arange(samples.time.size)) // self.bin_size
        edges = np.flatnonzero(np.diff(bins)) + 1
        for start, end in zip(np.concatenate([[0], edges]),
                              np.concatenate([edges, [bins.size]])):
            chosen: Set[int] = set()
            for column in columns:
                part = column[start:end]
                if np.isfinite(part).any():
                    chosen.update((start + int(np.nanargmin(part)),
                                   start + int(np.nanargmax(part))))
            points = [(first_index + index, float(samples.time[index]),
                       float(samples.ram_velocity[index]), float(torque[index]))
                      for index in sorted(chosen)]
            self._take(int(bins[start]), points)

    def _take(self, number: int, points: List[Tuple[int, float, float, float]]) -> None:
        if number != self._open_bin:
            self.kept += self._open
            self._open, self._open_bin = [], number
        self._open = self._thinned(self._open + points)

    @staticmethod
    def _thinned(points: List[Tuple[int, float, float, float]]
                 ) -> List[Tuple[int, float, float, float]]:
        """Return the points of least and greatest time, velocity and torque, by index."""
        chosen: Set[Tuple[int, float, float, float]] = set()
        for column in (1, 2, 3):
            finite = [point for point in points if math.isfinite(point[column])]
            if finite:
                chosen.add(min(finite, key=lambda point: point[column]))
                chosen.add(max(finite, key=lambda point: point[column]))
        return sorted(chosen or points)

    def trace(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the kept (time s, ram velocity m/s, input torque N m), in run order."""
        points = self.kept + self._open
        columns = np.array([point[1:] for point in points]).reshape(-1, 3)
        return columns[:, 0], columns[:, 1], columns[:, 2]


class TourWindows(NamedTuple):
    """What the streamed offset tour reads: each shown segment's last revolution, the trace."""

    samples: Samples  # the windows' samples, one after the other
    frames: np.ndarray  # the sample (of samples) each frame shows
    trace: Tuple[np.ndarray, np.ndarray, np.ndarray]  # time, ram velocity, input torque
    efforts_everywhere: bool  # whether every sample of the run carries a finite input torque


def read_tour(result: Analysis, offsets: int = 4, fps: float = 20.0,
              revolutions: float = 1.0, trace_bins: int = TRACE_BINS) -> TourWindows:
    """
    Read what the offset tour of a streamed run (analyse_file) draws, in one pass.

    The frames show what ``animation.offset_tour_samples`` picks from the whole run: the
    last ``revolutions`` of each of ``tour_segments``' segments, in real time at fps (stamps
    never step back within a segment: a step back splits it). None of it grows with the run.
    """
    recording = result.recording
    # Where each segment lies in the whole run (a whole-run analysis' segments index it).
    spans = (recording.extent.segment_spans if recording.extent else
             [(segment.start, segment.end) for segment in result.segments])
    windows = []  # (first index, end index, start time, end time) of each segment shown
    for index in tour_segments(result, offsets):
        row, segment = result.rows[index], result.segments[index]
        end_time = row['end_time']
        start_time = max(row['start_time'],
                         end_time - revolutions * 2 * math.pi / abs(segment.input_speed))
        if start_time < end_time:
            windows.append((*spans[index], start_time, end_time))
    kept: List[List[Samples]] = [[] for _ in windows]
    before: List[Optional[Samples]] = [None for _ in windows]
    envelope = TraceEnvelope(-(-recording.sample_count // max(1, trace_bins)))
    count, efforts_everywhere = 0, recording.efforts_recorded
    for checked in _checked_blocks(result):
        if not checked.stamps.size:
            continue
        samples = samples_of(checked, recording.time_origin_ns, recording.efforts_recorded)
        size = samples.time.size
        envelope.add(count, samples)
        efforts_everywhere = efforts_everywhere and samples.input_torque is not None and bool(
            np.isfinite(samples.input_torque).all())
        for number, (first, end, start_time, _) in enumerate(windows):
            low, high = max(first - count, 0), min(end - count, size)
            if low >= high:
                continue
            time = samples.time[low:high]
            earlier = np.flatnonzero(time < start_time)
            if earlier.size:  # the first frame may show the last sample before the window
                before[number] = _taken(samples, np.array([low + int(earlier[-1])]))
            later = low + np.flatnonzero(time >= start_time)
            if later.size:
                kept[number].append(_taken(samples, later))
        count += size
    pieces: List[Samples] = []
    frames: List[np.ndarray] = []
    shown = 0
    for (_, _, start_time, _), last_before, window in zip(windows, before, kept):
        window_samples = _joined(([] if last_before is None else [last_before]) + window)
        plan = frame_plan(window_samples.time, start_time, None, fps)
        frames.append(plan.sample + shown)
        pieces.append(window_samples)
        shown += window_samples.time.size
    samples = (_joined(pieces) if pieces else
               Samples._make(None if column is None else column[:0]
                             for column in recording.samples))
    return TourWindows(samples, np.concatenate(frames) if frames else np.zeros(0, int),
                       envelope.trace(), efforts_everywhere)


def write_window_tour(result: Analysis, path: str, offsets: int = 4, fps: float = 20.0,
                      revolutions: float = 1.0, trace_bins: int = TRACE_BINS) -> Optional[str]:
    """
    Write the main job's offset tour of a streamed run (analyse_file) into path.

    The frames of ``animation.write_offset_tour`` (read_tour); the input torque drawn when
    every sample of the run carries it. Returns the path written, or None when the run has
    no steady turning segment.
    """
    tour = read_tour(result, offsets, fps, revolutions, trace_bins)
    if not tour.frames.size:
        return None
    samples = tour.samples
    check_offsets(result.recording.geometry, samples.offset[tour.frames])
    time, velocity, torque = tour.trace
    efforts = samples.input_torque if tour.efforts_everywhere else None
    figure = LinkageFigure(result.recording.geometry, time, velocity,
                           torque if tour.efforts_everywhere else None, None,
                           largest_crank_radius(samples, tour.frames))
    try:
        frames = (rgb for _, rgb in render_frames(figure, samples, tour.frames,
                                                  segment_at(result), efforts))
        write_frames(frames, path, fps, tour.frames.size)
    finally:
        figure.close()
    return path


def _taken(samples: Samples, indices: np.ndarray) -> Samples:
    return Samples._make(None if column is None else column[indices] for column in samples)


def _joined(pieces: List[Samples]) -> Samples:
    return Samples._make(None if any(piece[index] is None for piece in pieces) else
                         np.concatenate([piece[index] for piece in pieces])
                         for index in range(len(Samples._fields)))
