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
Benchmark: one animation frame against a full redraw of the same figure, in this run.

The baseline is what a plain matplotlib loop does per frame: update the artists, redraw the
whole figure (``canvas.draw``) and copy the pixels. Measured: ``LinkageFigure.draw`` (only
the moving artists over a saved background), and the same plus the GIF palette mapping; then
the main job's tour (``write_offset_tour``) over the default schedule, in seconds, against
reading and analysing that run (which the main job does anyway). Prints medians and the
spread (min-max of the repeats).

    python3 dev.py run python bench/bench_animate.py [--frames 60] [--repeats 5]
"""

import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np
from PIL import Image

from qrm_ros import analysis
from qrm_ros.analysis import animation
from qrm_ros.analysis import linkage_figure
from qrm_ros.cli import qrm_main
from qrm_ros.core import kinematics as kin

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'test'))
from synthetic_run import write_run  # noqa: E402


def timed(function, repeats):
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        runs.append(time.perf_counter() - start)
    return statistics.median(runs), min(runs), max(runs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--frames', type=int, default=60)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()
    geometry = kin.Geometry.paper()
    with tempfile.TemporaryDirectory() as folder:
        run = os.path.join(folder, 'run.mcap')
        write_run(run, geometry, [o / 1e3 for o in qrm_main.DEFAULT_OFFSETS_MM], hold=4.0,
                  offset_rate=0.02)
        recording = analysis.read_recording(run)
        samples = recording.samples
        figure = linkage_figure.LinkageFigure(geometry, samples.time, samples.ram_velocity)
        indices = range(0, args.frames * 5, 5)
        text = animation.ratio_text(None)

        def blitted():
            for index in indices:
                figure.draw(samples.input_angle[index], samples.offset[index],
                            samples.time[index], samples.ram_velocity[index], text)

        def full_redraw():
            for _, artist in figure.moving:
                artist.set_animated(False)
            for index in indices:
                figure.update(samples.input_angle[index], samples.offset[index],
                              samples.time[index], samples.ram_velocity[index])
                figure.canvas.draw()
                np.asarray(figure.canvas.buffer_rgba())[:, :, :3].copy()
            for _, artist in figure.moving:
                artist.set_animated(True)

        palette = Image.fromarray(figure.draw(0.0, 0.0, 0.0, 0.0, text)).quantize(
            colors=128, method=Image.Quantize.MEDIANCUT)

        def blitted_and_mapped():
            for index in indices:
                rgb = figure.draw(samples.input_angle[index], samples.offset[index],
                                  samples.time[index], samples.ram_velocity[index], text)
                Image.fromarray(rgb).quantize(palette=palette, dither=Image.Dither.NONE)

        base = timed(full_redraw, args.repeats)
        per_frame = 1e3 / args.frames
        print(f'baseline full redraw: {base[0] * per_frame:.1f} ms/frame (spread '
              f'{base[1] * per_frame:.1f}-{base[2] * per_frame:.1f}, median of '
              f'{args.repeats} x {args.frames} frames, {linkage_figure.FRAME_SIZE[0]} x '
              f'{linkage_figure.FRAME_SIZE[1]} px)')
        for name, function in (('blitted draw', blitted),
                               ('blitted draw + GIF palette', blitted_and_mapped)):
            median, low, high = timed(function, args.repeats)
            print(f'{name}: {median * per_frame:.1f} ms/frame (spread {low * per_frame:.1f}-'
                  f'{high * per_frame:.1f}) = {median / base[0]:.2f}x the full redraw')
        figure.close()

        reading = timed(lambda: analysis.analyse(analysis.read_recording(run)), args.repeats)
        result = analysis.analyse(recording)
        frames = animation.offset_tour_samples(result).size
        tour = timed(lambda: animation.write_offset_tour(result, os.path.join(folder, 't.gif')),
                     args.repeats)
        print(f'baseline reading + analysing the default schedule\'s run '
              f'({samples.time.size} samples): {reading[0]:.2f} s')
        print(f'main job tour ({frames} frames, {os.path.getsize(os.path.join(folder, "t.gif"))}'
              f' bytes): {tour[0]:.2f} s (spread {tour[1]:.2f}-{tour[2]:.2f}) = '
              f'{tour[0] / reading[0]:.1f}x reading + analysing')


if __name__ == '__main__':
    main()
