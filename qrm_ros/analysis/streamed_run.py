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
A run of any length analysed in bounded memory: read, check, segment, measure by blocks.

``analyse_file`` gives what ``analyse(read_recording(path))`` gives, bit for bit (rows,
transitions, losses, counts), without holding the run. It reads the file twice. The first
pass checks every message (the same SampleChecks) and learns what the segmentation needs
of the whole run: the median step between stamps (from a count of each distinct step, so
its memory grows with the clock's jitter, not with the run's length), the largest commanded
speed, and whether any message carried efforts. The second pass segments as split_segments
does and measures each steady segment when it closes, holding only the open segment's
samples. The result's samples hold only what the figures draw (each segment's first
revolution; its ``segments`` index them); ``Recording.extent`` tells the whole run's size.
"""

import math
from typing import Any, Callable, Dict, Iterator, List, Optional, TextIO, Tuple

import numpy as np

from qrm_ros.analysis.joint_state_decoding import decoded_blocks, MessageCounter
from qrm_ros.analysis.measurement import Analysis, measure_segment, segment_geometry, with_stroke
from qrm_ros.analysis.recorded_drive import drive_changes, DriveSpan
from qrm_ros.analysis.recorded_run import (AnalysisError, JOINT_STATES_TOPIC, MIN_SEGMENT_SAMPLES,
                                           open_for_analysis, OpenedRun, progress_bar,
                                           PROGRESS_MIN_MESSAGES, Recording, RunExtent, Samples,
                                           samples_of, too_few_samples, with_recovery_losses)
from qrm_ros.analysis.sample_checks import CheckedBlock, SampleChecks
from qrm_ros.analysis.sample_consistency import foreign_geometry_problem
from qrm_ros.analysis.segments import (largest_speed, Segment, setting_changes, setting_speeds,
                                       speed_scale, STEADY_TOLERANCE, transition)

# The figures draw each segment's first input revolution; a segment standing still (input
# speed 0) never completes one, so its excerpt stops at this many samples.
MAX_EXCERPT_SAMPLES = 20_000


class RunSurvey:
    """The first pass: every check, and what segmenting needs to know of the whole run."""

    def __init__(self, opened: OpenedRun) -> None:
        self.opened = opened
        self.checks = SampleChecks(opened.geometry)
        self.origin_ns: Optional[int] = None
        self.drives: List[DriveSpan] = []
        self.step_counts: Dict[float, int] = {}
        self.earliest, self.latest = math.inf, -math.inf
        self.efforts_recorded = False
        self.largest_speed = {True: 0.0, False: 0.0}  # with efforts, without
        self._last_time: Optional[float] = None

    def add(self, checked: CheckedBlock) -> None:
        """Take in one checked block."""
        if not checked.stamps.size:
            return
        if self.origin_ns is None:
            self.origin_ns = int(checked.stamps[0])
            run, geometry, stored, drive, drive_problem = self.opened
            self.drives = [DriveSpan(-math.inf, drive, drive_problem),
                           *drive_changes(run, stored, geometry, self.origin_ns)]
        self.efforts_recorded |= not np.isnan(checked.efforts).all()
        for with_efforts in (True, False):
            speed, _ = setting_speeds(samples_of(checked, self.origin_ns, with_efforts),
                                      self.drives)
            self.largest_speed[with_efforts] = max(self.largest_speed[with_efforts],
                                                   largest_speed(speed))
        time = samples_of(checked, self.origin_ns, False).time
        self.earliest = min(self.earliest, float(time.min()))
        self.latest = max(self.latest, float(time.max()))
        before = [] if self._last_time is None else [self._last_time]
        steps = np.diff(np.concatenate([before, time]))
        values, counts = np.unique(steps[steps > 0], return_counts=True)
        for value, count in zip(values.tolist(), counts.tolist()):
            self.step_counts[value] = self.step_counts.get(value, 0) + count
        self._last_time = float(time[-1])

    def sample_period(self) -> Optional[float]:
        """Return the median positive step between stamps, as segments.sample_period."""
        total = sum(self.step_counts.values())
        if not total:
            return None
        wanted = [(total - 1) // 2, total // 2]  # the middle one or two, in sorted order
        found: List[float] = []
        seen = 0
        for value in sorted(self.step_counts):
            seen += self.step_counts[value]
            while len(found) < 2 and wanted[len(found)] < seen:
                found.append(value)
        return float(np.mean(found))  # as numpy's median: the mean of the middle two


class SegmentStream:
    """The second pass: segments as split_segments finds them, measured as they close."""

    def __init__(self, survey: RunSurvey) -> None:
        self.survey = survey
        self.geometry = survey.opened.geometry
        self.step = survey.sample_period() or 0.0
        self.scale = speed_scale(survey.largest_speed[survey.efforts_recorded])
        self.segments: List[Segment] = []
        self.rows: List[Dict[str, Any]] = []
        self.transitions: List[Dict[str, Any]] = []
        self.excerpts: List[Samples] = []  # each segment's first revolution
        self._count = 0  # samples seen
        self._last: Optional[Tuple[float, float, float, int, bool, float]] = None
        self._run: Optional[Dict[str, Any]] = None  # the open run of one setting
        self._largest_jump: Optional[float] = None  # since the last segment ended
        self._last_segment_end_time = 0.0

    def add(self, checked: CheckedBlock) -> None:
        """Take in one checked block (in file order)."""
        if not checked.stamps.size:
            return
        survey = self.survey
        samples = samples_of(checked, cast_int(survey.origin_ns), survey.efforts_recorded)
        speed, span = setting_speeds(samples, survey.drives)
        steady = samples.offset_rate == 0.0
        # The crank radius joint, where recorded: a stroke change splits as in split_segments.
        radius = (np.full(samples.time.shape, np.nan) if samples.crank_radius is None
                  else samples.crank_radius)
        if samples.crank_radius_rate is not None:
            steady = steady & (samples.crank_radius_rate == 0.0)
        base = self._count
        if self._last is None:  # the run's first sample opens the first run
            self._open(0, samples, 0, speed, span, steady, radius)
            columns: Tuple[np.ndarray, ...] = (samples.time, samples.offset, speed, span,
                                               steady, radius)
            carried = 0
        else:
            columns = tuple(np.concatenate([[before], now]) for before, now in zip(
                self._last, (samples.time, samples.offset, speed, span, steady, radius)))
            carried = 1
        time, offset, speeds, spans, steadies, radii = columns
        steps, gap, boundary = setting_changes(time, offset, speeds, spans, steadies, self.step,
                                               self.scale)
        with np.errstate(invalid='ignore'):  # NaN: no crank radius recorded, no split
            boundary = boundary | (np.abs(np.diff(radii)) > STEADY_TOLERANCE)
        position = 0
        for step in np.flatnonzero(boundary):
            self._track(steps[position:step], gap[position:step])
            local = int(step) + 1 - carried  # the block's sample that starts the next run
            self._close(base + local, samples, local)
            self._track(steps[step:step + 1], gap[step:step + 1])
            self._open(base + local, samples, local, speed, span, steady, radius)
            position = int(step) + 1
        self._track(steps[position:], gap[position:])
        if self._run is not None and self._run['pieces'] is not None:
            self._run['pieces'].append(_piece(samples, self._run['from'], None))
            self._run['from'] = 0
        self._count += samples.time.size
        self._last = (float(samples.time[-1]), float(samples.offset[-1]), float(speed[-1]),
                      int(span[-1]), bool(steady[-1]), float(radius[-1]))

    def finish(self) -> None:
        """Close the last run."""
        if self._run is not None:
            self._close(self._count, None, 0)

    def _track(self, steps: np.ndarray, gap: np.ndarray) -> None:
        """Keep the largest gap step (first of equals) since the last segment ended."""
        jumps = steps[gap]
        if jumps.size:
            largest = float(jumps[np.argmax(np.abs(jumps))])
            if self._largest_jump is None or abs(largest) > abs(self._largest_jump):
                self._largest_jump = largest

    def _open(self, start: int, samples: Samples, local: int, speed: np.ndarray,
              span: np.ndarray, steady: np.ndarray, radius: np.ndarray) -> None:
        recorded = float(radius[local])
        self._run = {'start': start, 'offset': float(samples.offset[local]),
                     'radius': recorded if math.isfinite(recorded) else None,
                     'speed': float(speed[local]), 'span': int(span[local]),
                     'pieces': [] if steady[local] else None, 'from': local,
                     'jump': self._largest_jump}

    def _close(self, end: int, samples: Optional[Samples], local: int) -> None:
        run = self._run
        assert run is not None
        self._run = None
        if run['pieces'] is None or end - run['start'] < MIN_SEGMENT_SAMPLES:
            return
        if samples is not None:
            run['pieces'].append(_piece(samples, run['from'], local))
        held = _joined(run['pieces'])
        drive = self.survey.drives[run['span']].drive
        segment = Segment(run['start'], end, run['offset'], run['speed'], drive, run['radius'])
        with np.errstate(all='ignore'):  # absurd recorded values give inf/NaN: null
            local_segment = segment._replace(start=0, end=end - run['start'])
            self.rows.append(with_stroke(measure_segment(
                held, local_segment, segment_geometry(self.geometry, segment), drive), segment,
                self.geometry))
        if self.segments:
            self.transitions.append(transition(self.segments[-1], segment,
                                               self._last_segment_end_time,
                                               float(held.time[0]), run['jump']))
        self.segments.append(segment)
        self._last_segment_end_time = float(held.time[-1])
        self._largest_jump = None
        self.excerpts.append(_first_revolution(held))

    def excerpt(self) -> Tuple[Samples, List[Segment]]:
        """Return the segments' first revolutions as one Samples, and segments indexing it."""
        segments, start = [], 0
        for segment, excerpt in zip(self.segments, self.excerpts):
            segments.append(segment._replace(start=start, end=start + excerpt.time.size))
            start += excerpt.time.size
        if not self.excerpts:
            empty = np.zeros(0)
            efforts = empty if self.survey.efforts_recorded else None
            return Samples._make([empty] * 9 + [efforts, efforts, None, None]), segments
        return _joined(self.excerpts), segments


def cast_int(value: Optional[int]) -> int:
    """Return value, known to be set once a block held samples."""
    assert value is not None
    return value


def _piece(samples: Samples, start: int, end: Optional[int]) -> Samples:
    return Samples._make(None if column is None else column[start:end] for column in samples)


def _joined(pieces: List[Samples]) -> Samples:
    if len(pieces) == 1:
        return pieces[0]
    return Samples._make(None if any(piece[index] is None for piece in pieces) else
                         np.concatenate([piece[index] for piece in pieces])
                         for index in range(len(Samples._fields)))


def _first_revolution(samples: Samples) -> Samples:
    """Return what the figures draw of a segment: its samples within one input revolution."""
    unwrapped = np.unwrap(samples.input_angle[:MAX_EXCERPT_SAMPLES])
    chosen = np.abs(unwrapped - unwrapped[0]) <= 2 * math.pi
    return Samples._make(None if column is None else column[:MAX_EXCERPT_SAMPLES][chosen]
                         for column in samples)


def _checked_blocks(opened: OpenedRun, checks: SampleChecks,
                    progress: Optional[Callable[[int], None]]) -> Iterator[CheckedBlock]:
    for block in decoded_blocks(opened.run, None, checks.file_losses, checks.rejected,
                                MessageCounter(), progress):
        yield checks.check(block)


def analyse_file(path: str, geometry_overrides: Optional[Dict[str, Optional[float]]] = None,
                 progress_stream: Optional[TextIO] = None) -> Analysis:
    """
    Read, check and measure a run file in bounded memory; AnalysisError if unusable.

    progress_stream: where a progress bar goes when it is a terminal (None: no bar).
    """
    opened = open_for_analysis(path, geometry_overrides)
    run = opened.run
    total = run.message_count(JOINT_STATES_TOPIC)
    bar = None
    if progress_stream is not None and progress_stream.isatty() and (
            total >= PROGRESS_MIN_MESSAGES):
        bar = progress_bar(progress_stream, 2 * total)  # a bar for a person, over both passes
    survey = RunSurvey(opened)
    for checked in _checked_blocks(opened, survey.checks, bar):
        survey.add(checked)
    checks = survey.checks
    losses = checks.losses(run)
    foreign = foreign_geometry_problem(path, opened.geometry, checks.inconsistent, checks.used)
    if foreign:
        raise AnalysisError(foreign)
    if checks.used < MIN_SEGMENT_SAMPLES:
        raise too_few_samples(path, checks.used, losses, run)
    stream = SegmentStream(survey)
    for checked in _checked_blocks(opened, SampleChecks(opened.geometry),
                                   None if bar is None else lambda done: bar(total + done)):
        stream.add(checked)
    stream.finish()
    if bar is not None:
        bar(2 * total)
    samples, segments = stream.excerpt()
    recording = Recording(
        path, opened.geometry, samples, run.problem if run.truncated else None, tuple(losses),
        checks.messages_in_file(run), checks.read, checks.repeated, opened.drive,
        opened.drive_problem, tuple(survey.drives[1:]), cast_int(survey.origin_ns),
        RunExtent(checks.used, survey.latest - survey.earliest, survey.efforts_recorded,
                  tuple((segment.start, segment.end) for segment in stream.segments)))
    recording = with_recovery_losses(recording, run.metadata)
    return Analysis(recording, segments, stream.rows, stream.transitions)
