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
Animations of recorded runs: which sample each frame shows, and the frames to GIF or MP4.

Each frame draws the linkage at one recorded joint state (qrm_ros.analysis.linkage_figure),
with a time-synced trace of the ram velocity (and of the input torque when the joint states
carry efforts), the offset in force and the measured TR and SR of the steady segment the
frame is in (from qrm_ros.analysis.measurement). A frame shows the last sample at or before
its time (a playback speed of 2 plays twice as fast as the run went), and its clock says
that sample's time.

GIF through Pillow; MP4 through the optional ``imageio-ffmpeg`` package (the ``video``
extra). The output is written all or nothing.
"""

import math
import os
from typing import (Any, Callable, cast, Dict, Iterable, Iterator, List, NamedTuple, Optional,
                    TextIO, Tuple)

import numpy as np

from qrm_ros.analysis.linkage_figure import FRAME_SIZE, LinkageFigure
from qrm_ros.analysis.measurement import analyse, Analysis
from qrm_ros.analysis.recorded_run import Recording, Samples
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import (absolute_topic, JOINT_NAMES, JOINT_STATE_TYPE,
                                       JOINT_STATES_TOPIC, PARAMETERS_METADATA)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.atomic_files import staged_outputs
from qrm_ros.recording.bag_reader import open_run, RunFileError

__all__ = ['AnimationError', 'FORMATS', 'FramePlan', 'MAX_FRAMES', 'MAX_GIF_FPS',
           'MP4_MISSING', 'animate_plan', 'check_offsets', 'check_output', 'check_rates',
           'frame_plan', 'gif_delay',
           'offset_tour_samples', 'ratio_text', 'read_efforts', 'recorded_cutting_length',
           'render_frames', 'segment_at', 'tour_segments', 'write_animation', 'write_frames',
           'write_offset_tour']

# Frames at most, by format: a GIF is assembled in memory (Pillow keeps every frame, 0.5 MB
# each, until written); an MP4 streams, but two hours is surely a mistaken span (a clock
# jump in the recording, a tiny --speed).
MAX_FRAMES = {'.gif': 600, '.mp4': 180_000}
# GIF frame delays are whole hundredths of a second, and viewers slow down delays under
# 0.02 s: a GIF plays exactly at 100 / k frames per second for a whole k >= 2.
MAX_GIF_FPS = 50.0
FORMATS = ('.gif', '.mp4')
MP4_MISSING = ('writing MP4 needs the optional imageio-ffmpeg package: pip install '
               "'qrm_ros[video]' (or imageio-ffmpeg), or write a .gif")
# The joints in names.JOINT_NAMES order, as the analysis' Samples take them.
INPUT_SHAFT, RAM, OFFSET = JOINT_NAMES[0], JOINT_NAMES[3], JOINT_NAMES[4]
# Frame times are a float sum; recorded stamps are whole nanoseconds apart.
_TIME_SLACK = 1e-12


class AnimationError(Exception):
    """Input or options that cannot be animated; the message is the one line shown."""


def gif_delay(fps: float) -> Optional[int]:
    """Return a GIF's frame delay in 1/100 s for fps, or None if no delay plays fps."""
    delay = 100.0 / fps
    whole = round(delay)
    return whole if whole >= 100.0 / MAX_GIF_FPS and abs(delay - whole) <= 1e-9 * delay else None


class FramePlan(NamedTuple):
    """Which recorded sample each frame shows, and the frame's own time (s)."""

    sample: np.ndarray
    time: np.ndarray


# frames/s: the frame rates a video player shows as motion (a frame every 10 s to a fast
# monitor's rate); ffmpeg itself fails, at length, on a rate such as 1e-300.
MIN_FPS = 0.1
MAX_FPS = 240.0


def check_rates(fps: float, speed: float, extension: str = '.mp4') -> None:
    """Refuse a frame rate or playback speed outside what the format can play."""
    if not (math.isfinite(fps) and fps > 0):
        raise AnimationError(f'--fps must be a positive number of frames per second, got {fps:g}')
    if not MIN_FPS <= fps <= MAX_FPS:
        raise AnimationError(f'--fps {fps:g} is out of range: allowed [{MIN_FPS:g}, '
                             f'{MAX_FPS:g}] frames per second')
    if extension == '.gif' and not gif_delay(fps):
        raise AnimationError(
            f'--fps {fps:g} cannot be played by a GIF, whose frame delays are whole hundredths '
            f'of a second (at least 2): use 100/k, e.g. {MAX_GIF_FPS:g}, 25, 20, 12.5 or 10, '
            'or write an .mp4')
    if not (math.isfinite(speed) and speed > 0):
        raise AnimationError(f'--speed must be a positive playback factor, got {speed:g}')


def frame_plan(sample_time: np.ndarray, start: Optional[float] = None,
               end: Optional[float] = None, fps: float = 25.0, speed: float = 1.0,
               extension: str = '.mp4',
               extent: Optional[Tuple[float, float]] = None) -> FramePlan:
    """
    Plan frames over [start, end] (s from the run's first sample) at fps, played at speed.

    Frame k is at start + k speed / fps and shows the last sample (by stamp) at or before
    it; a recording whose clock jumps back is taken in stamp order. ``extension`` sets the
    most frames allowed (MAX_FRAMES). ``extent``: the run's earliest and latest sample
    times when sample_time holds only a window of it (animation_window.read_window).
    """
    check_rates(fps, speed)
    order = np.argsort(sample_time, kind='stable')
    ordered = np.asarray(sample_time)[order]
    first, last = (float(ordered[0]), float(ordered[-1])) if extent is None else extent
    start = first if start is None else float(start)
    end = last if end is None else float(end)
    if not (math.isfinite(start) and math.isfinite(end)):
        raise AnimationError(f'--start and --end must be finite times in s, got {start:g} '
                             f'and {end:g}')
    if not first <= start < last:
        raise AnimationError(f'--start {start:g} s is outside the recording (allowed: '
                             f'{first:.3f} to {last:.3f} s)')
    if not end > start:
        raise AnimationError(f'empty span: --end ({end:g} s) must be after --start '
                             f'({start:g} s)')
    end = min(end, last)
    count = math.floor((end - start) * fps / speed + 1e-9) + 1
    if count > MAX_FRAMES[extension]:
        held = ', all held in memory' if extension == '.gif' else ''
        raise AnimationError(
            f'{count} frames ({end - start:g} s of run at --fps {fps:g} and --speed {speed:g}) '
            f'are too many for {extension} (at most {MAX_FRAMES[extension]}{held}): shorten '
            'the span with --start/--end, lower --fps or raise --speed'
            + (', or write an .mp4' if extension == '.gif' else ''))
    times = start + np.arange(count) * (speed / fps)
    shown = np.searchsorted(ordered, times + _TIME_SLACK, side='right') - 1
    return FramePlan(order[np.clip(shown, 0, ordered.size - 1)], times)


def ratio_text(row: Optional[Dict[str, Any]]) -> str:
    """Return the label of an analysis row (None: no segment): its measured TR and SR."""
    if row is None or not row['stroke_pairs']:
        return 'TR, SR: no whole stroke pair at steady settings here'
    ratios = [f'{name} {value:.4f}' for name, value in (
        ('TR', row['time_ratio_measured']), ('SR', row['speed_ratio_measured']))
        if value is not None and math.isfinite(value)]
    return ('  '.join(ratios or ['TR, SR: not measurable'])
            + f'  (measured, {row["stroke_pairs"]} pairs)')


def segment_at(result: Analysis) -> Callable[[float], Optional[Dict[str, Any]]]:
    """Return time -> the analysis row of the steady segment holding it, or None."""
    spans = [(row['start_time'], row['end_time'], row) for row in result.rows]

    def row_at(time):
        for start, end, row in spans:
            if start <= time <= end:
                return row
        return None
    return row_at


def render_frames(figure: LinkageFigure, samples: Samples, indices: Iterable[int],
                  row_at: Callable[[float], Optional[Dict[str, Any]]],
                  efforts: Optional[np.ndarray] = None) -> Iterator[Tuple[int, np.ndarray]]:
    """Yield (sample index, RGB frame) for each recorded sample index, drawn on figure."""
    for index in indices:
        time, offset = float(samples.time[index]), float(samples.offset[index])
        yield index, figure.draw(samples.input_angle[index], offset, time,
                                 samples.ram_velocity[index],
                                 ratio_text(row_at(time)),
                                 None if efforts is None else efforts[index],
                                 None if samples.crank_radius is None
                                 else float(samples.crank_radius[index]))


def read_efforts(path: str, samples: Samples) -> Optional[np.ndarray]:
    """
    Return the recorded input torque (N m) at each sample; None if a sample has none.

    Samples are matched to messages by stamp: the analysis' time zero is the stamp of the
    message its first sample came from (the same angle, offset and speeds, bit for bit).
    A run whose first message has no efforts (older recordings) costs one message.
    """
    from rosbags.typesys import get_typestore, Stores
    deserialize = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr
    first = (samples.input_angle[0], samples.offset[0], samples.input_speed[0],
             samples.ram_velocity[0])
    values: Any
    decoded: Any
    stamps, values, zero, decoded = [], [], None, None
    run = open_run(path)
    for message in run.messages([absolute_topic(JOINT_STATES_TOPIC)], log_time_order=False,
                                on_loss=lambda loss: None):  # the analysis lists losses
        first_message = decoded is None
        try:
            decoded = deserialize(message.data, JOINT_STATE_TYPE)
        except Exception:  # noqa: B902 - the analysis lists undecodable messages
            continue
        names = list(decoded.name)
        if len(decoded.effort) != len(names) or INPUT_SHAFT not in names:
            if first_message:
                return None
            continue
        stamp = decoded.header.stamp.sec * NANOSECONDS_PER_SECOND + decoded.header.stamp.nanosec
        if zero is None and len(decoded.position) == len(names) == len(decoded.velocity):
            position = dict(zip(names, decoded.position))
            velocity = dict(zip(names, decoded.velocity))
            if (position.get(INPUT_SHAFT), position.get(OFFSET), velocity.get(INPUT_SHAFT),
                    velocity.get(RAM)) == first:
                zero = stamp
        stamps.append(stamp)
        values.append(float(decoded.effort[names.index(INPUT_SHAFT)]))
    if zero is None:
        return None
    # As the analysis computes it.
    time = (np.asarray(stamps, dtype=np.int64) - zero) / NANOSECONDS_PER_SECOND
    order = np.argsort(time, kind='stable')
    time, values = time[order], np.asarray(values)[order]
    found = np.clip(np.searchsorted(time, samples.time), 0, time.size - 1)
    if not np.array_equal(time[found], samples.time):
        return None  # some sample's message has no effort
    efforts = values[found]
    return efforts if np.all(np.isfinite(efforts)) else None


def recorded_cutting_length(path: str) -> Optional[float]:
    """Workpiece length (m) from the recorded parameters when the run had a cutting load."""
    try:
        parameters = open_run(path).metadata.get(PARAMETERS_METADATA, {})
        force = float(parameters.get('cutting_force', 0.0))
        length = float(parameters.get('cutting_length', 0.0))
    except (RunFileError, ValueError):
        return None
    return length if force > 0.0 and 0.0 < length < math.inf else None


class _GifWriter:
    """Frames to a GIF through Pillow, one palette for all frames (no flicker)."""

    def __init__(self, path: str, fps: float) -> None:
        self.path, self.fps = path, fps

    def write(self, frames: Iterable[np.ndarray]) -> None:
        from PIL import Image
        palette = None

        def images():
            nonlocal palette
            for rgb in frames:
                image = Image.fromarray(rgb)
                if palette is None:  # every moving part is in the first frame
                    palette = image.quantize(colors=128, method=Image.Quantize.MEDIANCUT)
                yield image.quantize(palette=palette, dither=Image.Dither.NONE)

        sequence = images()
        first = next(sequence)
        delay = cast(int, gif_delay(self.fps))  # an fps no delay plays was refused (check_rates)
        first.save(self.path, format='GIF', save_all=True, append_images=sequence,
                   duration=10 * delay, loop=0)  # ms


class _Mp4Writer:
    """Frames to an H.264 MP4 through imageio-ffmpeg's bundled ffmpeg."""

    def __init__(self, path: str, fps: float) -> None:
        self.path, self.fps = path, fps

    def write(self, frames: Iterable[np.ndarray]) -> None:
        import imageio_ffmpeg
        writer = imageio_ffmpeg.write_frames(self.path, FRAME_SIZE, fps=self.fps, quality=7,
                                             macro_block_size=16, ffmpeg_log_level='error',
                                             output_params=['-f', 'mp4'])
        writer.send(None)
        try:
            for rgb in frames:
                writer.send(np.ascontiguousarray(rgb))
        finally:
            writer.close()


def check_output(path: str) -> str:
    """Refuse an output the animation cannot be written to; return its extension."""
    extension = os.path.splitext(path)[1].lower()
    if extension not in FORMATS:
        raise AnimationError(f'output {path!r} must end in .gif or .mp4')
    if extension == '.mp4':
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise AnimationError(MP4_MISSING) from None
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise AnimationError(f'the output folder {folder!r} does not exist')
    return extension


def write_frames(frames: Iterable[np.ndarray], path: str, fps: float, total: int,
                 progress_stream: Optional[TextIO] = None) -> int:
    """Write the RGB frames to path, all or nothing; return how many were written."""
    writer = _GifWriter if check_output(path) == '.gif' else _Mp4Writer
    progress = None
    if progress_stream is not None and progress_stream.isatty():  # a bar only for a person
        from tqdm import tqdm
        progress = tqdm(total=total, unit='frame', desc='drawing', file=progress_stream,
                        leave=False)
    count = 0

    def counted():
        nonlocal count
        for rgb in frames:
            yield rgb
            count += 1
            if progress is not None:
                progress.update(1)
    try:
        with staged_outputs() as stage:
            writer(stage(path), fps).write(counted())
    finally:
        if progress is not None:
            progress.close()
    return count


def check_offsets(geometry: kin.Geometry, offsets: np.ndarray) -> None:
    """Refuse recorded offsets the linkage cannot be drawn at."""
    try:
        kin.check_offset(geometry, offsets)
    except kin.KinematicsError as error:
        raise AnimationError(f'cannot draw the linkage: recorded {error}') from None


def write_animation(recording: Recording, path: str, start: Optional[float] = None,
                    end: Optional[float] = None, fps: float = 25.0, speed: float = 1.0,
                    result: Optional[Analysis] = None, efforts: Optional[np.ndarray] = None,
                    cutting_length: Optional[float] = None,
                    progress_stream: Optional[TextIO] = None) -> int:
    """
    Animate a recording (``recorded_run.read_recording``) over [start, end] into path.

    ``result``: its ``measurement.analyse`` (computed if not given), for the measured ratios;
    ``efforts``: input torque per sample (N m) or None. Returns the number of frames.
    """
    extension = check_output(path)
    check_rates(fps, speed, extension)
    samples = recording.samples
    plan = frame_plan(samples.time, start, end, fps, speed, extension)
    check_offsets(recording.geometry, samples.offset[plan.sample])
    result = result or analyse(recording)
    return animate_plan(recording.geometry, samples, plan, result, path, fps, efforts,
                        cutting_length, progress_stream)


def animate_plan(geometry: kin.Geometry, samples: Samples, plan: FramePlan, result: Analysis,
                 path: str, fps: float, efforts: Optional[np.ndarray] = None,
                 cutting_length: Optional[float] = None,
                 progress_stream: Optional[TextIO] = None) -> int:
    """Draw the planned frames of samples into path (write_animation); return the count."""
    # The traces cover the samples of the span, in recording order.
    span = slice(int(plan.sample.min()), int(plan.sample.max()) + 1)
    figure = LinkageFigure(geometry, samples.time[span], samples.ram_velocity[span],
                           None if efforts is None else efforts[span], cutting_length,
                           largest_crank_radius(samples, plan.sample))
    try:
        frames = (rgb for _, rgb in render_frames(figure, samples, plan.sample,
                                                  segment_at(result), efforts))
        return write_frames(frames, path, fps, plan.sample.size, progress_stream)
    finally:
        figure.close()


def largest_crank_radius(samples: Samples, indices: np.ndarray) -> Optional[float]:
    """Return the largest recorded crank radius (m) at these samples (None: not recorded)."""
    if samples.crank_radius is None or not np.size(indices):
        return None
    return float(np.max(samples.crank_radius[indices]))


def tour_segments(result: Analysis, offsets: int = 4) -> List[int]:
    """
    Return the indices (into result.segments) of the segments an offset tour shows.

    At each recorded stroke (crank radius), at most ``offsets``, spread over the offsets
    recorded there (first and last included); at each its turning segment with the most
    stroke pairs; in recording order.
    """
    chosen: Dict[Tuple[float, Optional[float]], Tuple[int, Dict[str, Any]]] = {}
    for index, (segment, row) in enumerate(zip(result.segments, result.rows)):
        key = (segment.offset, segment.crank_radius)
        held = chosen.get(key)
        if segment.input_speed != 0.0 and (
                held is None or row['stroke_pairs'] >= held[1]['stroke_pairs']):
            chosen[key] = (index, row)
    strokes: Dict[Optional[float], List[int]] = {}
    for index, _ in chosen.values():
        strokes.setdefault(result.segments[index].crank_radius, []).append(index)
    picked: List[int] = []
    for at_stroke in strokes.values():
        at_stroke.sort()  # segments are in recording order
        if len(at_stroke) > offsets:
            picks = np.unique(np.round(np.linspace(0, len(at_stroke) - 1,
                                                   offsets)).astype(int))
            at_stroke = [at_stroke[i] for i in picks]
        picked.extend(at_stroke)
    return sorted(picked)


def offset_tour_samples(result: Analysis, offsets: int = 4, fps: float = 20.0,
                        revolutions: float = 1.0) -> np.ndarray:
    """
    Sample indices of a short tour: the last revolution(s) at a few of the recorded offsets.

    At each recorded stroke (crank radius), ``offsets``: how many offsets at most, spread
    over those recorded there (first and last included); each shows the end of its segment
    with the most stroke pairs (a gap can split one offset's time into several), in real
    time at fps, in recording order. Empty when nothing turns.
    """
    samples = result.recording.samples
    indices = []
    for segment in (result.segments[index] for index in tour_segments(result, offsets)):
        times = samples.time[segment.start:segment.end]
        duration = revolutions * 2 * math.pi / abs(segment.input_speed)
        start = max(float(times.min()), float(times.max()) - duration)
        if start < float(times.max()):
            indices.append(frame_plan(times, start, None, fps).sample + segment.start)
    return np.concatenate(indices) if indices else np.array([], dtype=int)


def write_offset_tour(result: Analysis, path: str, offsets: int = 4, fps: float = 20.0,
                      revolutions: float = 1.0) -> Optional[str]:
    """
    Write a short animation beside the main job's figures (``offset_tour_samples``).

    With the input torque when the run recorded it. Returns the path written, or None when
    the run has no steady turning segment.
    """
    indices = offset_tour_samples(result, offsets, fps, revolutions)
    if not indices.size:
        return None
    samples = result.recording.samples
    check_offsets(result.recording.geometry, samples.offset[indices])
    efforts = read_efforts(result.recording.path, samples)
    figure = LinkageFigure(result.recording.geometry, samples.time, samples.ram_velocity,
                           efforts, None, largest_crank_radius(samples, indices))
    try:
        frames = (rgb for _, rgb in render_frames(figure, samples, indices,
                                                  segment_at(result), efforts))
        write_frames(frames, path, fps, indices.size)
    finally:
        figure.close()
    return path
