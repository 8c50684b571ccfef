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
"""The main job end to end, with a short schedule: real processes, real DDS, real files."""

import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys

from PIL import Image
import pytest

from qrm_ros.analysis import linkage_figure
from qrm_ros.cli import qrm_main
from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics.chain import Loads
from qrm_ros.node.process.ros_process import EXECUTOR_VARIABLE
from qrm_ros.recording.bag_reader import open_run

from ros_probe import installed_executable, stop_process, wait_for


def test_main_job_runs_a_short_schedule_end_to_end(tmp_path, capsys):
    # One stroke pair a second (250 Hz by default). At two a second (2 ms steps) a loaded
    # machine's late ticks near the sharp torque peak at 8 mm left its efforts unsupported
    # by the sampling (exit 3, said honestly; test_qrm_main_live says how).
    speed = 2 * math.pi
    code = qrm_main.main(['--offsets-mm', '-6', '8', '--pairs', '2', '--input-speed',
                          repr(speed), '--output-dir', str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    (folder,) = [p for p in tmp_path.iterdir() if p.name.startswith('qrm_')]
    for name in ('run.mcap', 'results.json', 'results.csv', 'shaper_sim.log',
                 'mcap_recorder.log'):
        assert (folder / name).is_file(), name
    assert sorted(os.listdir(folder / 'figures')) == sorted(
        ['fig10_time_ratio.png', 'fig11_speed_ratio.png', 'fig12_flywheel_speed.png',
         'ram_motion.png', 'fig_input_torque.png', 'fig_offset_cost.png',
         'fig_time_ratio_stroke.png', qrm_main.TOUR_FILE])
    # the last input revolution (1 s) of each offset at 20 frames per second, both ends,
    # at each recorded stroke: two offsets at the long one, two at the short one
    with Image.open(folder / 'figures' / qrm_main.TOUR_FILE) as tour:
        assert (tour.n_frames, tour.size) == (4 * 21, linkage_figure.FRAME_SIZE)
    assert f'qrm_main: animation  {folder / "figures" / qrm_main.TOUR_FILE}' in out
    assert str(folder / 'run.mcap') in out
    document = json.loads((folder / 'results.json').read_text())
    segments = document['segments']
    # The short-stroke experiment after the schedule: 60 mm at offset 0 (the quick return
    # lost), then the long stroke's time ratio held by the offset.
    short = [s for s in segments if abs(s['stroke_length'] - 0.06) < 1e-9]
    offsets = [s['offset'] for s in segments if s not in short]
    scheduled = [o for i, o in enumerate(offsets) if i == 0 or o != offsets[i - 1]]
    assert scheduled == [-0.006, 0.008]  # commanded, in order
    # A setting split in two is split by a gap in publication (a loaded machine), said so.
    gaps = [t for t in document['transitions']
            if t['kind'] == 'gap' and t['offset_from'] == t['offset_to']]
    assert len(offsets) - len(scheduled) <= len(gaps)
    geometry = kin.Geometry.paper()
    tolerance = (speed * 0.01) ** 3  # the stroke finder's bound at 100 Hz
    short_geometry = dataclasses.replace(geometry,
                                         crank_radius=0.06 * 0.113 / math.sqrt(0.16 + 0.0036))
    at_zero = [s for s in short if s['offset'] == 0.0 and s['stroke_pairs']]
    held = [s for s in short if s['offset'] > 0.0 and s['stroke_pairs']]
    assert at_zero and held
    for segment in at_zero:
        assert segment['time_ratio_measured'] == pytest.approx(
            kin.time_ratio_rk4(short_geometry, 0.0), rel=tolerance)
        assert segment['time_ratio_measured'] < 1.25
    for segment in held:
        assert segment['crank_radius'] == at_zero[0]['crank_radius']
        assert segment['time_ratio_measured'] == pytest.approx(kin.time_ratio(geometry, 0.0),
                                                               rel=tolerance)
    assert 'stroke 60.0 mm, time ratio 1.8367 held' in out
    for segment in segments:
        if segment in short:
            continue
        assert segment['stroke_pairs'] >= 2
        assert segment['input_speed'] == pytest.approx(speed, rel=1e-15)
        assert segment['time_ratio_measured'] == pytest.approx(
            kin.time_ratio_rk4(geometry, segment['offset']), rel=tolerance)
        eq25 = kin.speed_ratio_eq25(geometry, segment['offset'])
        assert segment['speed_ratio_measured'] == pytest.approx(eq25, rel=tolerance)
        # The main job's default loads (the small shaper's): inertia and gravity give back
        # what they take over a pair, so the drive's work per pair is the loads' work, one
        # cut of the workpiece plus friction over twice the stroke (dynamics.md).
        loads = Loads.small_shaper()
        loads_work = (loads.cutting_force * loads.cutting_length
                      + 2.0 * loads.ram_friction * geometry.ram_stroke)
        assert segment['stroke_pairs_with_efforts'] == segment['stroke_pairs']
        assert segment['energy_per_pair_theory'] == pytest.approx(loads_work, rel=1e-9)
        # Measured at 100 Hz: each of the four force jumps per pair (workpiece edges,
        # reversals) costs at most jump x speed x dt, 400 N x 0.3 m/s x 0.01 s = 1.2 J.
        assert segment['energy_per_pair_measured'] == pytest.approx(loads_work, abs=4 * 1.2)
        assert segment['speed_fluctuation_absolute_error'] == 0.0
        assert segment['peak_input_torque_relative_error'] is not None


@pytest.mark.parametrize('arguments, words', [
    (['--pairs', '0'], '--pairs must be at least 1'),
    (['--input-speed', 'nan'], '--input-speed must be finite and non-zero'),
    (['--offsets-mm', '0', '23'],
     '--offsets-mm: 23 mm is outside what shaper_sim accepts, |offset| <= 22.5 mm'),
    (['--pairs', 'three'], "--pairs: invalid int value: 'three'"),
    # What shaper_sim would refuse at start-up, by its own rules, live or offline.
    (['--offline', '--offset-rate-limit', '0'], 'shaper_sim would refuse it: '
     'offset_rate_limit = 0.0 refused: outside the allowed range [1e-06, 1] m/s'),
    (['--offset-rate-limit', '1e300'], 'offset_rate_limit = 1e+300 refused'),
    (['--offline', '--publish-rate', '1e-300'], 'shaper_sim would refuse it: '
     'publish_rate = 1e-300 refused: outside the allowed range [1, 10000] Hz'),
    (['--publish-rate', '1e300'], 'publish_rate = 1e+300 refused'),
])
def test_main_job_refuses_bad_options_with_exit_code_2(tmp_path, capsys, arguments, words):
    with pytest.raises(SystemExit) as stop:
        qrm_main.main(arguments + ['--output-dir', str(tmp_path)])
    assert stop.value.code == 2
    errors = [line for line in capsys.readouterr().err.splitlines()
              if line.startswith('qrm_main: error:')]
    assert len(errors) == 1 and words in errors[0], errors
    assert not list(tmp_path.iterdir())  # nothing started, nothing written


@pytest.mark.parametrize('offline', [True, False], ids=['offline', 'live'])
@pytest.mark.parametrize('where, words', [
    ('a file', 'cannot make the run folder there (Not a directory)'),
    ('/proc/qrm', 'cannot make the run folder there (No such file or directory)'),
])
def test_an_output_dir_that_takes_no_folder_is_refused(tmp_path, capsys, offline, where,
                                                       words):
    output = tmp_path / 'a file'
    output.write_text('not a folder')
    output_dir = str(output) if where == 'a file' else where
    with pytest.raises(SystemExit) as stop:
        qrm_main.main(['--offsets-mm', '0', '--pairs', '1', '--output-dir', output_dir]
                      + (['--offline'] if offline else []))
    assert stop.value.code == 2
    errors = [line for line in capsys.readouterr().err.splitlines()
              if line.startswith('qrm_main: error:')]
    assert errors == [f'qrm_main: error: --output-dir {output_dir!r}: {words}']
    assert [p.name for p in tmp_path.iterdir()] == ['a file']


def _gone(pid):
    """Whether a process has ended (a zombie waiting for init to reap it counts as ended)."""
    try:
        with open(f'/proc/{pid}/stat') as handle:
            return handle.read().rsplit(')', 1)[1].split()[0] in ('Z', 'X')
    except FileNotFoundError:
        return True


@pytest.mark.parametrize('signal_number, moment', [
    (signal.SIGTERM, 'recording'), (signal.SIGINT, 'recording'), (signal.SIGTERM, 'starting'),
], ids=['SIGTERM-recording', 'SIGINT-recording', 'SIGTERM-starting'])
def test_a_stop_signal_stops_the_children_cleanly(tmp_path, signal_number, moment):
    executable = installed_executable('qrm_main')
    command = [executable] if executable else [sys.executable, '-m', 'qrm_ros.cli.qrm_main']
    out, err = tmp_path / 'out', tmp_path / 'err'
    with open(out, 'w') as out_file, open(err, 'w') as err_file:
        job = subprocess.Popen(command + ['--offsets-mm', '5', '--pairs', '1000',
                                          '--output-dir', str(tmp_path / 'runs')],
                               stdout=out_file, stderr=err_file)
    try:
        wanted = 'started shaper_sim' if moment == 'starting' else 'started mcap_recorder'
        wait_for(lambda: wanted in out.read_text() or job.poll() is not None, 30.0, wanted)
        (folder,) = (tmp_path / 'runs').iterdir()
        if moment == 'recording':
            # A first chunk of messages on disk (closed after 1 s of log time).
            wait_for(lambda: (folder / 'run.mcap').exists() and os.path.getsize(
                folder / 'run.mcap') > 4096, 30.0, 'the recorder writing a chunk')
        code = stop_process(job, signal_number, timeout=60.0)
    finally:
        if job.poll() is None:
            job.kill()
    text = out.read_text() + err.read_text()
    assert code == 128 + signal_number, text
    assert f'qrm_main: interrupted by {signal.Signals(signal_number).name}' in err.read_text()
    for name in ('shaper_sim', 'mcap_recorder'):
        log = folder / f'{name}.log'
        if log.exists():
            assert 'Traceback' not in log.read_text(), log.read_text()
    assert 'Traceback' not in text, text
    pids = [int(pid) for pid in re.findall(r'started \S+ \(pid (\d+)\)', text)]
    assert pids and all(_gone(pid) for pid in pids), text
    if moment == 'recording':
        run = open_run(folder / 'run.mcap')
        assert not run.truncated and run.problem is None
        assert sum(1 for _ in run.messages(['/joint_states'])) > 0


def test_a_failure_while_running_exits_1_with_one_line(tmp_path, capsys, monkeypatch):
    # The options are all good (the main job checks shaper_sim's values before it starts);
    # the child inherits an executor choice it refuses at start-up.
    monkeypatch.setenv(EXECUTOR_VARIABLE, 'no_such_executor')
    code = qrm_main.main(['--offsets-mm', '0', '--pairs', '1', '--output-dir', str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 1, err
    errors = [line for line in err.splitlines() if line.startswith('qrm_main: error:')]
    assert len(errors) == 1 and 'shaper_sim exited (2)' in errors[0], err
    (folder,) = tmp_path.iterdir()
    assert EXECUTOR_VARIABLE in (folder / 'shaper_sim.log').read_text()


def test_the_report_says_figures_the_sampling_cannot_support(tmp_path, capsys):
    """qrm_main's report lacks what qrm_analyze's exit 3 lacks (report.shortfalls)."""
    from synthetic_run import write_run
    coarse = tmp_path / 'coarse.mcap'
    write_run(coarse, kin.Geometry.paper(), [0.01], hold=20.0, rate=10.0)
    missing = qrm_main.report(str(coarse), str(tmp_path))
    err = capsys.readouterr().err
    assert missing and all('by the sampling' in line for line in missing)
    assert all(f'qrm_main: warning: {line}' in err for line in missing)


@pytest.mark.parametrize('speed, rate', [(2 * math.pi, 250.0), (4 * math.pi, 500.0),
                                         (math.pi, 125.0), (0.5, 100.0), (100.0, 1000.0)])
def test_the_default_rate_gives_250_samples_a_revolution_within_its_range(speed, rate):
    assert qrm_main.default_publish_rate(speed) == rate
    assert qrm_main.default_publish_rate(-speed) == rate
