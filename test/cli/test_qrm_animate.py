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
"""qrm_animate on recorded runs: what it writes, what it refuses, and its exit codes."""

import importlib.metadata
import math
import os
import subprocess
import sys

import pytest
from PIL import Image

from qrm_ros.analysis import animation
from qrm_ros.analysis import linkage_figure
from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from qrm_ros.cli import qrm_animate
from qrm_ros.core import kinematics as kin
from damaged_runs import cases, put_together, take_apart
from synthetic_run import write_run, write_truncated_run
from repo_paths import TEST_DATA

PAPER = kin.Geometry.paper()


GOLDEN = TEST_DATA


def _gif_frames(path):
    with Image.open(path) as image:
        durations = []
        for index in range(image.n_frames):
            image.seek(index)
            durations.append(image.info['duration'])
        return image.n_frames, image.size, durations


def test_gif_has_one_frame_per_planned_time_at_the_frame_size(
        tmp_path, capsys, run_with_efforts):
    out = tmp_path / 'run.gif'
    code = qrm_animate.main([str(run_with_efforts), '-o', str(out), '--start', '0.5', '--end',
                             '2.5', '--fps', '20', '--speed', '2'])
    stdout, stderr = capsys.readouterr()
    assert code == 0, stderr
    count = math.floor((2.5 - 0.5) * 20 / 2) + 1
    assert stdout.strip() == f'{out}: {count} frames, 800 x 640 px, 20 fps, {count / 20:.2f} s'
    frames, size, durations = _gif_frames(out)
    assert (frames, size) == ((count, linkage_figure.FRAME_SIZE))
    assert durations == [50] * count
    assert [p for p in os.listdir(tmp_path) if p != 'run.gif'] == []  # no temporary left


def test_repeated_frames_keep_the_gif_playing_in_real_time(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=1.0, rate=20.0)
    out = tmp_path / 'slow.gif'
    # 0.1 s of run at a tenth of real speed and 50 fps: each sample shows for 5 frames.
    assert qrm_animate.main([str(path), '-o', str(out), '--end', '0.1', '--fps', '50',
                             '--speed', '0.1']) == 0
    assert '51 frames' in capsys.readouterr().out
    frames, _, durations = _gif_frames(out)
    assert sum(durations) == 51 * 20  # Pillow merges identical frames, adding their delays
    assert frames == 3  # samples at 0, 0.05 and 0.1 s


def test_console_script_is_installed_and_runs(tmp_path, run_with_efforts):
    scripts = {entry.name: entry.value
               for entry in importlib.metadata.entry_points(group='console_scripts')}
    assert scripts['qrm_animate'] == 'qrm_ros.cli.entry_points:qrm_animate'
    out = tmp_path / 'run.gif'
    done = subprocess.run(
        [sys.executable, '-c', 'import sys; from qrm_ros.cli import entry_points; '
         'sys.exit(entry_points.qrm_animate())', str(run_with_efforts), '-o', str(out),
         '--end', '0.5', '--fps', '10'], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f'{out}: 6 frames, 800 x 640 px, 10 fps, 0.60 s\n'
    assert done.stderr == ''  # no progress bar when stderr is not a terminal


def test_offset_tour_shows_the_last_revolution_of_a_few_segments(tmp_path):
    path = tmp_path / 'run.mcap'
    offsets = [-0.01, -0.005, 0.0, 0.005, 0.01, 0.015]
    write_run(path, PAPER, offsets, hold=1.6, offset_rate=0.05)
    result = measurement.analyse(recorded_run.read_recording(str(path)))
    assert [row['offset'] for row in result.rows] == offsets
    indices = animation.offset_tour_samples(result, offsets=4, fps=20.0)
    samples = result.recording.samples
    shown = sorted(set(samples.offset[indices]))
    assert shown == [-0.01, 0.0, 0.005, 0.015]  # first and last included, spread between
    for offset in shown:
        times = samples.time[indices][samples.offset[indices] == offset]
        assert times.size == 21  # one revolution (1 s) at 20 fps, both ends
        segment = next(s for s in result.segments if s.offset == offset)
        assert times[-1] == samples.time[segment.end - 1]
    out = tmp_path / 'tour.gif'
    assert animation.write_offset_tour(result, str(out), offsets=4, fps=20.0) == str(out)
    frames, size, _ = _gif_frames(out)
    assert (frames, size) == (indices.size, linkage_figure.FRAME_SIZE)


def test_offset_tour_shows_each_offset_once_when_a_gap_splits_it(tmp_path):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0, 0.01], hold=3.0, offset_rate=0.05)
    recorded = take_apart(path.read_bytes())
    joints = recorded.joint_states()
    lost = {id(m) for m in joints[100:110]}  # 0.1 s lost 1 s into the first offset
    recorded.messages[:] = [m for m in recorded.messages if id(m) not in lost]
    split = tmp_path / 'split.mcap'
    split.write_bytes(put_together(recorded))
    result = measurement.analyse(recorded_run.read_recording(str(split)))
    assert [row['offset'] for row in result.rows] == [0.0, 0.0, 0.01]
    indices = animation.offset_tour_samples(result, offsets=4, fps=20.0)
    samples = result.recording.samples
    assert sorted(set(samples.offset[indices])) == [0.0, 0.01]
    longer = result.segments[1]  # 1.9 s after the gap, against 1.0 s before it
    assert longer.end - longer.start > result.segments[0].end - result.segments[0].start
    first = indices[samples.offset[indices] == 0.0]
    assert first.min() >= longer.start and first.max() == longer.end - 1


def _run(arguments, capsys):
    code = qrm_animate.main([str(a) for a in arguments])
    out, err = capsys.readouterr()
    return code, out, err


def test_file_without_joint_states_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=1.0, joint_states_topic='/other_states')
    code, _, err = _run([path, '-o', tmp_path / 'x.gif'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert err.count('\n') == 1 and err.startswith('qrm_animate: error: ')
    assert 'no /joint_states topic' in err and '/other_states' in err
    assert not (tmp_path / 'x.gif').exists()


def test_unknown_geometry_exits_2_and_names_the_options(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=1.0, with_geometry=False)
    code, _, err = _run([path, '-o', tmp_path / 'x.gif'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT and err.count('\n') == 1
    assert 'has no qrm_ros.geometry metadata' in err and '--crank-radius' in err
    options = ['--coupling-radius', '0.025', '--crank-radius', '0.0505', '--pivot-distance',
               '0.113', '--ram-height', '0.2']
    code, _, err = _run([path, '-o', tmp_path / 'x.gif', '--end', '0.2'] + options, capsys)
    assert code == 0, err


@pytest.mark.parametrize('arguments, words', [
    (['--start', '1.5', '--end', '1'],
     'empty span: --end (1 s) must be after --start (1.5 s)'),
    (['--start', '40'], '--start 40 s is outside the recording (allowed: 0.000 to 1.990 s)'),
    (['--fps', '0'], '--fps must be a positive number of frames per second, got 0'),
    (['--fps', '60'], '--fps 60 cannot be played by a GIF, whose frame delays are whole '
     'hundredths of a second (at least 2): use 100/k, e.g. 50, 25, 20, 12.5 or 10, or write '
     'an .mp4'),
    (['--fps', '30'], '--fps 30 cannot be played by a GIF'),
    (['--fps', '1e-300'], '--fps 1e-300 is out of range: allowed [0.1, 240] frames per second'),
    (['--speed', 'nan'], '--speed must be a positive playback factor, got nan'),
    (['--fps', '50', '--speed', '0.1'], '996 frames (1.99 s of run at --fps 50 and --speed '
     '0.1) are too many for .gif (at most 600, all held in memory): shorten the span with '
     '--start/--end, lower --fps or raise --speed, or write an .mp4'),
])
def test_bad_span_or_rates_exit_2_with_one_line(tmp_path, capsys, arguments, words):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=2.0)
    code, _, err = _run([path, '-o', tmp_path / 'x.gif'] + arguments, capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert err.startswith(f'qrm_animate: error: {words}') and err.count('\n') == 1, err
    assert os.listdir(tmp_path) == ['run.mcap']


@pytest.mark.parametrize('output, words', [
    ('x.avi', "output '{folder}/x.avi' must end in .gif or .mp4"),
    ('missing/x.gif', "the output folder '{folder}/missing' does not exist"),
])
def test_bad_output_exits_2_before_reading(tmp_path, capsys, output, words):
    code, _, err = _run([tmp_path / 'does_not_matter.mcap', '-o', tmp_path / output], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert err == f'qrm_animate: error: {words.format(folder=tmp_path)}\n'


def test_mp4_without_imageio_ffmpeg_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, 'imageio_ffmpeg', None)  # as if not installed
    code, _, err = _run([os.path.join(GOLDEN, 'steady_positive_offset.mcap'), '-o',
                         tmp_path / 'x.mp4'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert err == f'qrm_animate: error: {animation.MP4_MISSING}\n'
    assert "'qrm_ros[video]'" in err and 'imageio-ffmpeg' in err and '.gif' in err


def test_an_output_that_cannot_be_written_exits_1_and_leaves_nothing(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=1.0)
    (tmp_path / 'taken.gif').mkdir()  # a folder where the file should go
    code, _, err = _run([path, '-o', tmp_path / 'taken.gif', '--end', '0.2'], capsys)
    assert code == exit_codes.EXIT_FAILURE
    assert err.startswith(f'qrm_animate: error: cannot write {tmp_path / "taken.gif"}')
    assert err.endswith('no animation was written\n') and err.count('\n') == 1
    assert sorted(os.listdir(tmp_path)) == ['run.mcap', 'taken.gif']
    assert os.listdir(tmp_path / 'taken.gif') == []


def test_truncated_recording_is_animated_and_exits_3(tmp_path, capsys):
    cut = write_truncated_run(tmp_path)
    code, out, err = _run([cut, '-o', tmp_path / 'cut.gif', '--fps', '5'], capsys)
    assert code == exit_codes.EXIT_INCOMPLETE
    assert 'truncated' in err and 'the animation covers only what was readable' in err
    frames, size, _ = _gif_frames(tmp_path / 'cut.gif')
    assert f'{frames} frames' in out and size == linkage_figure.FRAME_SIZE


def test_mp4_has_the_frame_count_and_size(tmp_path, capsys, run_with_efforts):
    imageio_ffmpeg = pytest.importorskip('imageio_ffmpeg')
    out = tmp_path / 'run.mp4'
    code, stdout, err = _run([run_with_efforts, '-o', out, '--end', '1.0', '--fps', '30'],
                             capsys)
    assert code == 0, err
    assert '31 frames' in stdout
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    count = sum(1 for _ in reader)
    assert (count, tuple(meta['size']), meta['fps']) == (31, linkage_figure.FRAME_SIZE, 30.0)
    assert os.listdir(tmp_path) == ['run.mp4']


# Two of each kind of damage or oddity by default; qrm_analyze's own fuzz test runs 300.
FUZZ_CASES = int(os.environ.get('QRM_ANIMATE_FUZZ_CASES', '14'))


@pytest.fixture(scope='module')
def fuzz_cases():
    logs = {name: open(os.path.join(GOLDEN, f'{name}.mcap'), 'rb').read()
            for name in ('steady_positive_offset', 'offset_and_speed_change')}
    return cases(logs, FUZZ_CASES, seed=20261122)


@pytest.mark.parametrize('number', range(FUZZ_CASES))
def test_damaged_run_is_animated_or_refused_as_qrm_analyze_does(number, fuzz_cases, tmp_path,
                                                                capsys):
    case = fuzz_cases[number]
    run = tmp_path / 'run.mcap'
    run.write_bytes(case.data)
    analysed = qrm_analyze.main([str(run)])
    capsys.readouterr()
    out = tmp_path / 'run.gif'
    code, stdout, err = _run([run, '-o', out, '--fps', '1', '--speed', '8'], capsys)
    context = f'{case.name}: exit {code} (qrm_analyze: {analysed})\n{err}'
    assert 'Traceback' not in stdout + err, context
    # A clock that jumps by days makes an animation of days: refused, with what to do.
    assert code == analysed or (code == 2 and ' are too many for .gif' in err), context
    written = ['run.gif'] if code != exit_codes.EXIT_BAD_INPUT else []
    assert sorted(os.listdir(tmp_path)) == sorted(['run.mcap'] + written), context
    if code == exit_codes.EXIT_BAD_INPUT:
        assert err.startswith('qrm_animate: error: ') and err.count('\n') == 1, context
    else:
        frames, size, _ = _gif_frames(out)
        assert f'{frames} frames' in stdout and size == linkage_figure.FRAME_SIZE, context
