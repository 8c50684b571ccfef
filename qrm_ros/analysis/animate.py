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
Animations of recorded runs: ``qrm_animate RUN.mcap -o OUT.gif|.mp4`` (no ROS needed).

Each frame draws the linkage at one recorded joint state (the recorded input angle and
offset through ``qrm_ros.core.linkage``, so every pin is where the kinematics core puts it), with
a time-synced trace of the ram velocity (and of the input torque when the joint states carry
efforts), the offset in force and the measured TR and SR of the steady segment the frame is
in (from ``qrm_ros.analysis.run_analysis``). A frame shows the last sample at or before its time
(``--speed 2`` plays twice as fast as the run went), and its clock says that sample's time.

GIF through Pillow; MP4 through the optional ``imageio-ffmpeg`` package (the ``video``
extra). Exit status as qrm_analyze's: 0 written; 1 rendering or writing failed (nothing
written); 2 bad options or nothing usable in the file (one line says why); 3 written, but
the recording was damaged or incomplete (stderr says what was lost).
"""

import argparse
import math
import os
import sys
from typing import NamedTuple

import matplotlib
matplotlib.use('Agg')
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402
import numpy as np  # noqa: E402

from qrm_ros.analysis import run_analysis as analysis  # noqa: E402
from qrm_ros.core import kinematics as kin  # noqa: E402
from qrm_ros.analysis.run_analysis import (AnalysisError, EXIT_BAD_INPUT,  # noqa: E402
                                           EXIT_FAILURE, EXIT_INCOMPLETE, EXIT_OK)
from qrm_ros.recording.atomic_files import staged_outputs  # noqa: E402
from qrm_ros.recording.bag_reader import open_run, RunFileError  # noqa: E402
from qrm_ros.analysis.design_table import add_geometry_arguments  # noqa: E402
from qrm_ros.core.linkage import (COLOURS, linkage_points, linkage_sizes,  # noqa: E402
                                  workpiece_span)
from qrm_ros.core.names import (absolute_topic, JOINT_NAMES, JOINT_STATE_TYPE,  # noqa: E402
                                JOINT_STATES_TOPIC, PARAMETERS_METADATA)
from qrm_ros.core.units import NANOSECONDS_PER_SECOND  # noqa: E402

__all__ = ['AnimationError', 'FORMATS', 'FRAME_SIZE', 'FramePlan', 'LinkageFigure',
           'MAX_FRAMES', 'MAX_GIF_FPS', 'MP4_MISSING', 'check_output', 'check_rates',
           'frame_plan', 'main', 'offset_tour_samples', 'ratio_text', 'read_efforts',
           'render_frames', 'segment_at', 'write_animation', 'write_offset_tour']

# Pixels (width, height): multiples of 16, as H.264 encoders want.
FRAME_SIZE = (800, 640)
_DPI = 100
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


def _colour(name):
    return COLOURS[name][:3]


def _gif_delay(fps):
    """Return a GIF's frame delay in 1/100 s for fps, or None if no delay plays fps."""
    delay = 100.0 / fps
    whole = round(delay)
    return whole if whole >= 100.0 / MAX_GIF_FPS and abs(delay - whole) <= 1e-9 * delay else None


class FramePlan(NamedTuple):
    """Which recorded sample each frame shows, and the frame's own time (s)."""

    sample: np.ndarray
    time: np.ndarray


def check_rates(fps, speed, extension='.mp4'):
    """Refuse a frame rate or playback speed outside what the format can play."""
    if not (math.isfinite(fps) and fps > 0):
        raise AnimationError(f'--fps must be a positive number of frames per second, got {fps:g}')
    if extension == '.gif' and not _gif_delay(fps):
        raise AnimationError(
            f'--fps {fps:g} cannot be played by a GIF, whose frame delays are whole hundredths '
            f'of a second (at least 2): use 100/k, e.g. {MAX_GIF_FPS:g}, 25, 20, 12.5 or 10, '
            'or write an .mp4')
    if not (math.isfinite(speed) and speed > 0):
        raise AnimationError(f'--speed must be a positive playback factor, got {speed:g}')


def frame_plan(sample_time, start=None, end=None, fps=25.0, speed=1.0, extension='.mp4'):
    """
    Plan frames over [start, end] (s from the run's first sample) at fps, played at speed.

    Frame k is at start + k speed / fps and shows the last sample (by stamp) at or before
    it; a recording whose clock jumps back is taken in stamp order. ``extension`` sets the
    most frames allowed (MAX_FRAMES).
    """
    check_rates(fps, speed)
    order = np.argsort(sample_time, kind='stable')
    ordered = np.asarray(sample_time)[order]
    first, last = float(ordered[0]), float(ordered[-1])
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


class LinkageFigure:
    """
    One figure redrawn per frame: the linkage on top, the time-synced traces below.

    Only the moving artists are redrawn (blitting); ``drawn_points`` reads back what they
    show, so tests can compare the picture with the kinematics core.
    """

    def __init__(self, geometry, time, ram_velocity, effort=None, cutting_length=None):
        self.geometry = geometry
        self.sizes = sizes = linkage_sizes(geometry)
        width, height = FRAME_SIZE
        self.figure = Figure(figsize=(width / _DPI, height / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.figure)
        grid = self.figure.add_gridspec(2, 1, height_ratios=(2.2, 1.0), left=0.1, right=0.88,
                                        top=0.90, bottom=0.08, hspace=0.25)
        self.axes = axes = self.figure.add_subplot(grid[0])
        self.trace_axes = self.figure.add_subplot(grid[1])
        self._draw_static(axes, geometry, sizes, cutting_length)
        line = dict(linewidth=4, solid_capstyle='round')
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
        text = dict(transform=self.figure.transFigure, va='top', family='monospace',
                    fontsize=10)
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
        for _, artist in self.moving + [(axes, self.ratios)]:
            artist.set_animated(True)
        self.canvas.draw()
        self.bare = self.background = self.canvas.copy_from_bbox(self.figure.bbox)

    def _draw_static(self, axes, geometry, sizes, cutting_length):
        h = geometry.pivot_distance
        guide = 0.5 * (float(geometry.ram_stroke) + sizes.ram_length)
        rail = 0.5 * (sizes.ram_thickness + sizes.bar_width)
        ram_y = sizes.ram_line_height
        grey = _colour('frame_grey')
        axes.plot([0, 0], [0, -h], color=grey, linewidth=6, zorder=0)
        for y in (ram_y + rail, ram_y - rail):
            axes.plot([-guide, guide], [y, y], color=grey, linewidth=2, zorder=0)
        axes.add_patch(Circle((0, 0), sizes.flywheel_radius, color=_colour('flywheel_blue'),
                              alpha=0.35, zorder=1))
        top = ram_y - sizes.tool_drop
        if cutting_length:
            low, high = workpiece_span(geometry, cutting_length, sizes)
            axes.add_patch(Rectangle((low, top - sizes.ram_thickness), high - low,
                                     sizes.ram_thickness, color=_colour('workpiece_brown'),
                                     zorder=1))
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

    def draw(self, input_angle, offset, time, ram_velocity, ratios, effort=None):
        """Draw one state (ratios: ``ratio_text``); return it as (height, width, 3) uint8."""
        ratios = '\n\n' + ratios  # below the clock and the offset
        if ratios != self.ratios.get_text():
            self.ratios.set_text(ratios)
            self.canvas.restore_region(self.bare)
            self.axes.draw_artist(self.ratios)
            self.background = self.canvas.copy_from_bbox(self.figure.bbox)
        self.update(input_angle, offset, time, ram_velocity, effort)
        self.canvas.restore_region(self.background)
        for axes, artist in self.moving:
            axes.draw_artist(artist)
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()

    def update(self, input_angle, offset, time, ram_velocity, effort=None):
        """Move the moving artists to one state, without drawing them."""
        points = linkage_points(self.geometry, offset, input_angle, sizes=self.sizes)
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

    def drawn_points(self):
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
            'cursor_time': float(self.cursor.get_xdata()[0]),
        }
        if self.torque_dot is not None:
            drawn['torque_dot'] = np.column_stack(self.torque_dot.get_data())[0]
        return drawn

    def close(self):
        self.figure.clear()


def ratio_text(row):
    """Return the label of an analysis row (None: no segment): its measured TR and SR."""
    if row is None or not row['stroke_pairs']:
        return 'TR, SR: no whole stroke pair at steady settings here'
    ratios = [f'{name} {value:.4f}' for name, value in (
        ('TR', row['time_ratio_measured']), ('SR', row['speed_ratio_measured']))
        if value is not None and math.isfinite(value)]
    return ('  '.join(ratios or ['TR, SR: not measurable'])
            + f'  (measured, {row["stroke_pairs"]} pairs)')


def segment_at(result):
    """Return time -> the analysis row of the steady segment holding it, or None."""
    spans = [(row['start_time'], row['end_time'], row) for row in result.rows]

    def row_at(time):
        for start, end, row in spans:
            if start <= time <= end:
                return row
        return None
    return row_at


def render_frames(figure, samples, indices, row_at, efforts=None):
    """Yield (sample index, RGB frame) for each recorded sample index, drawn on figure."""
    for index in indices:
        time, offset = float(samples.time[index]), float(samples.offset[index])
        yield index, figure.draw(samples.input_angle[index], offset, time,
                                 samples.ram_velocity[index],
                                 ratio_text(row_at(time)),
                                 None if efforts is None else efforts[index])


def read_efforts(path, samples):
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


def _cutting_length(path):
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

    def __init__(self, path, fps):
        self.path, self.fps = path, fps

    def write(self, frames):
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
        first.save(self.path, format='GIF', save_all=True, append_images=sequence,
                   duration=10 * _gif_delay(self.fps), loop=0)  # ms


class _Mp4Writer:
    """Frames to an H.264 MP4 through imageio-ffmpeg's bundled ffmpeg."""

    def __init__(self, path, fps):
        self.path, self.fps = path, fps

    def write(self, frames):
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


def check_output(path):
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


def _write(frames, path, fps, total, progress_stream=None):
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


def _check_offsets(geometry, offsets):
    try:
        kin.check_offset(geometry, offsets)
    except kin.KinematicsError as error:
        raise AnimationError(f'cannot draw the linkage: recorded {error}') from None


def write_animation(recording, path, start=None, end=None, fps=25.0, speed=1.0, result=None,
                    efforts=None, cutting_length=None, progress_stream=None):
    """
    Animate a recording (``analysis.read_recording``) over [start, end] into path.

    ``result``: its ``analysis.analyse`` (computed if not given), for the measured ratios;
    ``efforts``: input torque per sample (N m) or None. Returns the number of frames.
    """
    extension = check_output(path)
    check_rates(fps, speed, extension)
    samples = recording.samples
    plan = frame_plan(samples.time, start, end, fps, speed, extension)
    _check_offsets(recording.geometry, samples.offset[plan.sample])
    result = result or analysis.analyse(recording)
    # The traces cover the samples of the span, in recording order.
    span = slice(int(plan.sample.min()), int(plan.sample.max()) + 1)
    figure = LinkageFigure(recording.geometry, samples.time[span], samples.ram_velocity[span],
                           None if efforts is None else efforts[span], cutting_length)
    try:
        frames = (rgb for _, rgb in render_frames(figure, samples, plan.sample,
                                                  segment_at(result), efforts))
        return _write(frames, path, fps, plan.sample.size, progress_stream)
    finally:
        figure.close()


def offset_tour_samples(result, offsets=4, fps=20.0, revolutions=1.0):
    """
    Sample indices of a short tour: the last revolution(s) at a few of the recorded offsets.

    ``offsets``: how many offsets at most, spread over those recorded (first and last
    included); each shows the end of its segment with the most stroke pairs (a gap can
    split one offset's time into several), in real time at fps. Empty when nothing turns.
    """
    samples = result.recording.samples
    chosen = {}
    for segment, row in zip(result.segments, result.rows):
        held = chosen.get(segment.offset)
        if segment.input_speed != 0.0 and (
                held is None or row['stroke_pairs'] >= held[1]['stroke_pairs']):
            chosen[segment.offset] = (segment, row)
    segments = sorted((segment for segment, _ in chosen.values()), key=lambda s: s.start)
    if len(segments) > offsets:
        picks = np.unique(np.round(np.linspace(0, len(segments) - 1, offsets)).astype(int))
        segments = [segments[i] for i in picks]
    indices = []
    for segment in segments:
        times = samples.time[segment.start:segment.end]
        duration = revolutions * 2 * math.pi / abs(segment.input_speed)
        start = max(float(times.min()), float(times.max()) - duration)
        if start < float(times.max()):
            indices.append(frame_plan(times, start, None, fps).sample + segment.start)
    return np.concatenate(indices) if indices else np.array([], dtype=int)


def write_offset_tour(result, path, offsets=4, fps=20.0, revolutions=1.0):
    """
    Write a short animation beside the main job's figures (``offset_tour_samples``).

    With the input torque when the run recorded it. Returns the path written, or None when
    the run has no steady turning segment.
    """
    indices = offset_tour_samples(result, offsets, fps, revolutions)
    if not indices.size:
        return None
    samples = result.recording.samples
    _check_offsets(result.recording.geometry, samples.offset[indices])
    efforts = read_efforts(result.recording.path, samples)
    figure = LinkageFigure(result.recording.geometry, samples.time, samples.ram_velocity,
                           efforts)
    try:
        frames = (rgb for _, rgb in render_frames(figure, samples, indices,
                                                  segment_at(result), efforts))
        _write(frames, path, fps, indices.size)
    finally:
        figure.close()
    return path


def _parser():
    parser = argparse.ArgumentParser(
        prog='qrm_animate',
        description='Animate a recorded run: the linkage at each recorded joint state, with '
                    'ram velocity (and input torque when recorded), the offset in force and '
                    'the measured TR and SR of the steady segment.',
        epilog='Exit status: 0 written; 1 rendering or writing failed (nothing written); 2 '
               'bad options or nothing usable in the file; 3 written, but the recording was '
               'damaged or incomplete (stderr says what was lost).')
    parser.add_argument('run', help='recorded run (.mcap) from mcap_recorder')
    parser.add_argument('-o', '--output', required=True, metavar='OUT',
                        help='animation to write: OUT.gif (Pillow) or OUT.mp4 (needs the '
                             'imageio-ffmpeg package, extra qrm_ros[video])')
    parser.add_argument('--start', type=float, default=None, metavar='S',
                        help='start time [s] after the first joint state (default: 0)')
    parser.add_argument('--end', type=float, default=None, metavar='S',
                        help='end time [s] after the first joint state (default: the last)')
    parser.add_argument('--fps', type=float, default=25.0, metavar='N',
                        help='frames per second [1/s] of the animation, > 0; for a GIF 100/k '
                             f'for a whole k >= 2 (at most {MAX_GIF_FPS:g}) (default: 25)')
    parser.add_argument('--speed', type=float, default=1.0, metavar='X',
                        help='playback speed [-]: run seconds per animation second, > 0 '
                             '(default: 1)')
    geometry_group = parser.add_argument_group(
        'geometry', 'override (or supply, for files without it) the stored geometry')
    add_geometry_arguments(geometry_group, defaults=False)
    return parser


def main(argv=None):
    """Run qrm_animate; return the exit status (see the module's docstring)."""
    args = _parser().parse_args(argv)
    overrides = {name: getattr(args, name) for name in analysis.GEOMETRY_FIELDS}
    try:
        check_rates(args.fps, args.speed, check_output(args.output))
        recording = analysis.read_recording(args.run, overrides, progress_stream=sys.stderr)
        count = write_animation(recording, args.output, args.start, args.end, args.fps,
                                args.speed, efforts=read_efforts(args.run, recording.samples),
                                cutting_length=_cutting_length(args.run),
                                progress_stream=sys.stderr)
    except (AnimationError, AnalysisError, RunFileError) as error:
        print(f'qrm_animate: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as error:
        # the one output; error.filename may be its temporary name
        print(f'qrm_animate: error: cannot write {args.output}: '
              f'{error.strerror or error}; no animation was written', file=sys.stderr)
        return EXIT_FAILURE
    except Exception as error:  # noqa: B902 - ffmpeg, Pillow or matplotlib failing mid-way
        print(f'qrm_animate: error: writing {args.output} failed ({type(error).__name__}: '
              f'{error}); no animation was written', file=sys.stderr)
        return EXIT_FAILURE
    print(f'{args.output}: {count} frames, {FRAME_SIZE[0]} x {FRAME_SIZE[1]} px, '
          f'{args.fps:g} fps, {count / args.fps:.2f} s')
    lines = analysis.incompleteness(recording)
    for line in lines:
        print(f'qrm_animate: warning: {line}', file=sys.stderr)
    if lines:
        print('qrm_animate: warning: the animation covers only what was readable and usable',
              file=sys.stderr)
        return EXIT_INCOMPLETE
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
