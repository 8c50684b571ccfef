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
"""

import math
from typing import Iterator, List, NamedTuple, Optional, TextIO, Tuple

import numpy as np

from qrm_ros.analysis.animation import (animate_plan, check_offsets, check_output, check_rates,
                                        frame_plan)
from qrm_ros.analysis.joint_state_decoding import decoded_blocks, MessageCounter
from qrm_ros.analysis.measurement import Analysis
from qrm_ros.analysis.recorded_run import Samples, samples_of
from qrm_ros.analysis.sample_checks import CheckedBlock, SampleChecks
from qrm_ros.recording.bag_reader import open_run

__all__ = ['RunWindow', 'read_window', 'write_window_animation']

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


def _taken(samples: Samples, indices: np.ndarray) -> Samples:
    return Samples._make(None if column is None else column[indices] for column in samples)


def _joined(pieces: List[Samples]) -> Samples:
    return Samples._make(None if any(piece[index] is None for piece in pieces) else
                         np.concatenate([piece[index] for piece in pieces])
                         for index in range(len(Samples._fields)))
