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
Offline analysis against the closed form, on synthetic runs written without ROS.

The synthetic joint states are the core's exact states sampled at 100 Hz, so the measured
ratios may differ from theory only by the stroke finder's interpolation error, bounded by
(|w| dt)^3 = 2.5e-4 at 2 pi rad/s and 100 Hz (test_strokes derives that bound).
"""

import io
import json
import math
import os

import numpy as np
import pytest

from qrm_ros.analysis import joint_state_decoding
from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import report
from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from qrm_ros.recording import bag_reader
from qrm_ros.analysis import figures
from qrm_ros.core import kinematics as kin
from synthetic_run import schedule_states, write_run
from repo_paths import TEST_DATA

PAPER = kin.Geometry.paper()
SCHEDULE = [-0.015, -0.0111725663716814, 0.0, 0.008, 0.015]
TOLERANCE = (2 * math.pi * 0.01) ** 3


def samples_for(offsets, input_speed=2 * math.pi, **kwargs):
    time, angle, offset, offset_velocity, state = schedule_states(
        PAPER, offsets, input_speed=input_speed, **kwargs)
    return recorded_run.Samples(time, angle, np.full_like(time, input_speed),
                                state.flywheel_angle, state.flywheel_speed, state.ram_position,
                                state.ram_velocity, offset, offset_velocity)


@pytest.fixture(scope='module')
def schedule_analysis():
    recording = recorded_run.Recording('synthetic', PAPER, samples_for(SCHEDULE), None)
    return measurement.analyse(recording)


def test_segments_are_exactly_the_commanded_offsets(schedule_analysis):
    assert [row['offset'] for row in schedule_analysis.rows] == SCHEDULE
    assert len(schedule_analysis.transitions) == len(SCHEDULE) - 1
    for row in schedule_analysis.rows:
        assert row['stroke_pairs'] >= 3


@pytest.mark.parametrize('name', ['time_ratio', 'speed_ratio', 'peak_speed_ratio'])
def test_measured_ratios_match_closed_form(schedule_analysis, name):
    function = {'time_ratio': kin.time_ratio, 'speed_ratio': kin.speed_ratio,
                'peak_speed_ratio': kin.peak_speed_ratio}[name]
    for row in schedule_analysis.rows:
        expected = function(PAPER, row['offset'])
        assert row[f'{name}_theory'] == pytest.approx(expected, rel=1e-12)
        assert row[f'{name}_measured'] == pytest.approx(expected, rel=TOLERANCE)
        assert abs(row[f'{name}_relative_error']) < TOLERANCE


def test_unity_speed_ratio_offset_measures_one(schedule_analysis):
    row = schedule_analysis.rows[1]
    assert row['speed_ratio_measured'] == pytest.approx(1.0, rel=TOLERANCE)


def test_stroke_times_and_speeds_match_closed_form(schedule_analysis):
    for row in schedule_analysis.rows:
        cutting, returning = kin.stroke_times(PAPER, row['offset'], 2 * math.pi)
        assert row['cutting_time_measured'] == pytest.approx(cutting, rel=TOLERANCE)
        assert row['return_time_measured'] == pytest.approx(returning, rel=TOLERANCE)
        peak_cut, peak_ret = kin.peak_ram_speeds(PAPER, row['offset'], 2 * math.pi)
        assert row['peak_cutting_speed_measured'] == pytest.approx(peak_cut, rel=TOLERANCE)
        assert row['peak_return_speed_measured'] == pytest.approx(peak_ret, rel=TOLERANCE)


def test_reverse_running_gives_the_inverse_ratios():
    recording = recorded_run.Recording(
        'reverse', PAPER, samples_for([0.01], input_speed=-2 * math.pi), None)
    (row,) = measurement.analyse(recording).rows
    assert row['time_ratio_measured'] == pytest.approx(1 / kin.time_ratio(PAPER, 0.01),
                                                       rel=TOLERANCE)
    assert row['time_ratio_measured'] < 1.0


def test_figures_are_written_and_theory_curves_are_the_core(schedule_analysis, tmp_path):
    paths = figures.write_figures(schedule_analysis, str(tmp_path))
    assert sorted(os.path.basename(p) for p in paths) == sorted(figures.FIGURES)
    for path in paths:
        with open(path, 'rb') as handle:
            assert handle.read(8) == b'\x89PNG\r\n\x1a\n'
        assert os.path.getsize(path) > 20_000

    def theory_lines(figure):
        return [line for axes in figure.axes for line in axes.get_lines()
                if line.get_gid() == figures.THEORY]

    h = PAPER.pivot_distance
    tr_lines = theory_lines(figures.time_ratio_figure(schedule_analysis))
    x, y = tr_lines[0].get_data()
    checked = [kin.time_ratio_rk4(PAPER, d) for d in x[::50] * h]  # the paper's method
    np.testing.assert_allclose(y[::50], checked, rtol=1e-9)
    family = [line for axes in figures.time_ratio_figure(schedule_analysis).axes
              for line in axes.get_lines() if line.get_gid() == figures.THEORY_FAMILY]
    assert len(family) == len(figures.OTHER_CRANK_RADII)
    for line, crank_radius in zip(family, figures.OTHER_CRANK_RADII):
        other = kin.Geometry(PAPER.coupling_radius, crank_radius, PAPER.pivot_distance)
        x, y = line.get_data()
        checked = [kin.time_ratio_rk4(other, d) for d in x[::80] * h]
        np.testing.assert_allclose(y[::80], checked, rtol=1e-9)
    mid, peak = theory_lines(figures.speed_ratio_figure(schedule_analysis))
    x, y = mid.get_data()
    r1, r = PAPER.coupling_radius, PAPER.crank_radius
    np.testing.assert_allclose(y, (h + r) * (r1 + x * h) / ((h - r) * (r1 - x * h)), rtol=1e-12)
    x, y = peak.get_data()
    np.testing.assert_allclose(y, kin.peak_speed_ratio(PAPER, x * h), rtol=1e-12)
    for line, row in zip(theory_lines(figures.flywheel_speed_figure(schedule_analysis)),
                         schedule_analysis.rows):
        theta, omega2 = line.get_data()
        theta = np.radians(theta)
        d = row['offset']
        eq4 = 2 * math.pi * r1 * (r1 + d * np.sin(theta)) / (r1 ** 2 + d ** 2
                                                             + 2 * r1 * d * np.sin(theta))
        np.testing.assert_allclose(omega2, eq4, rtol=1e-12)
    lines = theory_lines(figures.ram_motion_figure(schedule_analysis))
    assert len(lines) == 2 * len(schedule_analysis.rows)


def run_main(args, capsys):
    code = qrm_analyze.main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert 'Traceback' not in err
    return code, out, err


def test_file_round_trip_json_and_csv(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [-0.01, 0.01], hold=3.0)
    code, out, err = run_main([path, '--json', tmp_path / 'r.json', '--csv', tmp_path / 'r.csv',
                               '--plot', tmp_path / 'figs'], capsys)
    assert code == 0, err
    assert '-10.00' in out and '10.00' in out
    document = json.loads((tmp_path / 'r.json').read_text())
    assert document['geometry']['crank_radius'] == 0.0505
    offsets = [segment['offset'] for segment in document['segments']]
    assert offsets == [-0.01, 0.01]
    for segment in document['segments']:
        for key in ('offset', 'input_speed', 'stroke_pairs', 'time_ratio_measured',
                    'time_ratio_theory', 'speed_ratio_measured', 'speed_ratio_theory',
                    'peak_speed_ratio_measured', 'peak_speed_ratio_theory'):
            assert key in segment
        assert segment['input_speed'] == pytest.approx(2 * math.pi)
        assert segment['time_ratio_measured'] == pytest.approx(
            kin.time_ratio(PAPER, segment['offset']), rel=TOLERANCE)
    rows = (tmp_path / 'r.csv').read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith('offset,')
    assert len(list((tmp_path / 'figs').iterdir())) == len(figures.FIGURES)


def test_missing_file(tmp_path, capsys):
    code, _, err = run_main([tmp_path / 'nothing.mcap'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert 'does not exist' in err and len(err.strip().splitlines()) == 1


def test_not_an_mcap_file(tmp_path, capsys):
    path = tmp_path / 'notes.mcap'
    path.write_text('just some text\n')
    code, _, err = run_main([path], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert 'not an MCAP file' in err


def test_truncated_file_is_analysed_up_to_what_is_whole(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0, 0.01], hold=3.0, chunk_size=16 * 1024)
    data = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:int(len(data) * 0.8)])
    code, out, err = run_main([cut], capsys)
    assert code == exit_codes.EXIT_INCOMPLETE
    assert 'truncated' in err
    assert '0.00' in out  # the first offset's strokes were whole


def test_file_without_joint_states(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], joint_states_topic='/other_states')
    code, _, err = run_main([path], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert 'no /joint_states topic' in err and '/other_states' in err


def test_file_without_geometry_needs_options(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.005], with_geometry=False, hold=3.0)
    code, _, err = run_main([path], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert 'no qrm_ros.geometry metadata' in err and '--coupling-radius' in err
    code, out, err = run_main([path, '--coupling-radius', 0.025, '--crank-radius', 0.0505,
                               '--pivot-distance', 0.113, '--ram-height', 0.2], capsys)
    assert code == 0, err
    assert '5.00' in out


def test_bad_geometry_option(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=2.0)
    code, _, err = run_main([path, '--crank-radius', 0.5], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert 'crank_radius' in err and 'pivot_distance' in err


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_bar_only_on_a_terminal_and_long_files(tmp_path, monkeypatch):
    path = tmp_path / 'run.mcap'
    count = write_run(path, PAPER, [0.0], hold=60.0)
    terminal, pipe = Terminal(), io.StringIO()
    recorded_run.read_recording(str(path), progress_stream=pipe)
    recorded_run.read_recording(str(path), progress_stream=terminal)
    assert pipe.getvalue() == '' and terminal.getvalue() == ''  # too short for a bar
    monkeypatch.setattr(recorded_run, 'PROGRESS_MIN_MESSAGES', 100)
    recorded_run.read_recording(str(path), progress_stream=terminal)
    bar = terminal.getvalue()
    assert bar.startswith('\rreading joint states [') and bar.endswith('] 100%\n')
    assert bar.count('\r') == count // 5000 + 1


def test_parallel_decoding_gives_the_same_samples_as_serial(tmp_path, monkeypatch):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [-0.01, 0.01], hold=15.0, chunk_size=16 * 1024)
    serial = recorded_run.read_recording(str(path)).samples
    monkeypatch.setattr(recorded_run, 'PARALLEL_MIN_MESSAGES', 0)
    monkeypatch.setattr(recorded_run, 'usable_cores', lambda: 3)
    parts = bag_reader.open_run(str(path)).parts(3)
    assert len(parts) == 3  # really split
    parallel = recorded_run.read_recording(str(path)).samples
    for name, values in serial._asdict().items():
        np.testing.assert_array_equal(getattr(parallel, name), values, err_msg=name)


def test_coarse_sampling_is_flagged(capsys):
    coarse = recorded_run.Recording('coarse', PAPER, samples_for([0.01], rate=25.0), None)
    fine = recorded_run.Recording('fine', PAPER, samples_for([0.01], rate=100.0), None)
    (coarse_row,) = measurement.analyse(coarse).rows
    (fine_row,) = measurement.analyse(fine).rows
    assert coarse_row['samples_per_revolution'] == pytest.approx(25.0)
    assert fine_row['samples_per_revolution'] == pytest.approx(100.0)
    assert 'only 25 samples per input revolution' in report.format_table(
        measurement.analyse(coarse))
    assert 'warning' not in report.format_table(measurement.analyse(fine))


# --- gaps, damage, outputs and exit codes ---------------------------------------------------

def _with_jump(samples, at, seconds):
    """Shift the stamps from sample `at` on: a pause (> 0, the motion resumes where it
    stopped) or a clock jump back (< 0)."""
    time = samples.time.copy()
    time[at:] += seconds
    return samples._replace(time=time)


@pytest.mark.parametrize('seconds', [3.0, 0.05, -2.0])
def test_a_gap_inside_a_steady_segment_splits_it_and_is_listed(seconds):
    steady = samples_for([0.01], hold=8.0)
    middle = steady.time.size // 2 + 7
    result = measurement.analyse(recorded_run.Recording('paused', PAPER, _with_jump(
        steady, middle, seconds), None))
    assert [(row['offset'], row['input_speed']) for row in result.rows] == [
        (0.01, 2 * math.pi)] * 2
    assert [(s.start, s.end) for s in result.segments] == [(0, middle),
                                                           (middle, steady.time.size)]
    (gap,) = result.transitions
    assert gap['kind'] == 'gap' and gap['offset_from'] == gap['offset_to'] == 0.01
    assert (f'gap of {seconds + 0.01:.3f} s' if seconds > 0
            else f'jumps back by {-seconds - 0.01:.3f} s') in gap['change']
    expected = kin.time_ratio(PAPER, 0.01)
    for row in result.rows:  # no stroke measured across the gap
        assert row['time_ratio_measured'] == pytest.approx(expected, rel=TOLERANCE)
        assert row['time_ratio_measured_std'] < TOLERANCE


def test_a_gap_of_a_few_periods_is_tolerated():
    steady = samples_for([0.01], hold=8.0)
    jittered = _with_jump(steady, 300, 0.019)  # a 2.9-period step: still one segment
    (row,) = measurement.analyse(recorded_run.Recording('late', PAPER, jittered, None)).rows
    assert row['stroke_pairs'] >= 6


def _chunk_indexes(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as handle:
        return sorted(make_reader(handle).get_summary().chunk_indexes,
                      key=lambda c: c.chunk_start_offset)


def _log_times(path):
    """Log times of every joint state, by rosbags' own MCAP reader (independent)."""
    from pathlib import Path
    from rosbags.highlevel import AnyReader
    with AnyReader([Path(path)]) as reader:
        return [log_time for _, log_time, _ in reader.messages(connections=reader.connections)]


def _messages_between(path, start, end):
    return sum(1 for log_time in _log_times(path) if start <= log_time <= end)


def _damage(path, offset, target):
    data = bytearray(path.read_bytes())
    data[offset:offset + 8] = b'\xa5' * 8
    target.write_bytes(bytes(data))
    return target


@pytest.mark.parametrize('chunk', [0, 3])
@pytest.mark.parametrize('parallel', [False, True])
def test_a_damaged_chunk_is_skipped_and_what_it_held_reported(tmp_path, capsys, monkeypatch,
                                                              chunk, parallel):
    path = tmp_path / 'run.mcap'
    total = write_run(path, PAPER, [-0.01, 0.01], hold=6.0, chunk_size=16 * 1024)
    index = _chunk_indexes(path)[chunk]
    held = _messages_between(path, index.message_start_time, index.message_end_time)
    damaged = _damage(path, index.chunk_start_offset + 80, tmp_path / 'damaged.mcap')
    if parallel:  # the path of long files: worker processes, one part each
        monkeypatch.setattr(recorded_run, 'PARALLEL_MIN_MESSAGES', 0)
        monkeypatch.setattr(recorded_run, 'usable_cores', lambda: 3)
    code, out, err = run_main([damaged, '--json', tmp_path / 'r.json'], capsys)
    assert code == exit_codes.EXIT_INCOMPLETE, err
    document = json.loads((tmp_path / 'r.json').read_text())
    assert not document['complete']
    assert document['messages'] == {'in_file': total, 'read': total - held,
                                    'used': total - held, 'repeated': 0}
    (loss,) = document['losses']
    assert loss['stage'] == 'file' and loss['messages'] == held
    assert f'damaged chunk at byte {index.chunk_start_offset}' in loss['reason']
    every = _log_times(path)
    lost = [t for t in every if index.message_start_time <= t <= index.message_end_time]
    assert loss['start_time'] == pytest.approx((min(lost) - min(every)) * 1e-9, abs=1e-12)
    assert loss['end_time'] == pytest.approx((max(lost) - min(every)) * 1e-9, abs=1e-12)
    assert f'{held} /joint_states messages lost, log time {loss["start_time"]:.3f} s' in err
    if chunk:  # the lost second is a gap inside the first offset's segment
        assert any(t['kind'] == 'gap' for t in document['transitions'])


def test_a_damaged_chunk_of_an_unfinished_file_ends_the_readable_part(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0, 0.01], hold=4.0, chunk_size=16 * 1024)
    indexes = _chunk_indexes(path)
    data = path.read_bytes()[:indexes[-1].chunk_start_offset]  # no summary: streamed
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data)
    damaged = _damage(cut, indexes[4].chunk_start_offset + 80, tmp_path / 'damaged.mcap')
    code, _, err = run_main([damaged, '--json', tmp_path / 'r.json'], capsys)
    assert code == exit_codes.EXIT_INCOMPLETE
    document = json.loads((tmp_path / 'r.json').read_text())
    readable = _messages_between(path, 0, indexes[4].message_start_time - 1)
    assert document['messages']['read'] == readable
    assert 'the record there is damaged' in document['truncated']
    assert [loss['messages'] for loss in document['losses']] == [None]  # unknown, and said
    assert 'an unknown number of /joint_states messages lost' in err


def test_every_chunk_damaged_is_nothing_usable(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0], hold=2.0)
    (index,) = _chunk_indexes(path)
    damaged = _damage(path, index.chunk_start_offset + 80, tmp_path / 'damaged.mcap')
    code, _, err = run_main([damaged, '--json', tmp_path / 'r.json'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT and len(err.strip().splitlines()) == 1
    assert 'holds 0 usable /joint_states messages' in err
    assert 'damaged chunk at byte' in err
    assert not (tmp_path / 'r.json').exists()


def test_outputs_are_all_or_nothing(tmp_path, capsys):
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.01], hold=3.0)
    (tmp_path / 'plots').write_text('a file where the figures folder should be')
    code, _, err = run_main([path, '--json', tmp_path / 'r.json', '--csv', tmp_path / 'r.csv',
                             '--plot', tmp_path / 'plots'], capsys)
    assert code == exit_codes.EXIT_FAILURE
    assert len(err.strip().splitlines()) == 1 and 'no output file was written' in err
    assert sorted(os.listdir(tmp_path)) == ['plots', 'run.mcap']  # no JSON, CSV or temporary
    code, _, err = run_main([path, '--json', tmp_path / 'missing' / 'r.json', '--csv',
                             tmp_path / 'r.csv'], capsys)
    assert code == exit_codes.EXIT_FAILURE and 'missing' in err
    assert sorted(os.listdir(tmp_path)) == ['plots', 'run.mcap']
    (tmp_path / 'r.json').write_text('the previous results')
    code, _, _ = run_main([path, '--json', tmp_path / 'r.json'], capsys)
    assert code == exit_codes.EXIT_OK
    assert json.loads((tmp_path / 'r.json').read_text())['complete'] is True
    assert oct(os.stat(tmp_path / 'r.json').st_mode & 0o777) == oct(0o666 & ~_umask())


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_json_holds_null_where_a_figure_is_not_finite(capsys):
    recording = recorded_run.Recording('huge', PAPER, samples_for([0.01]), None)
    result = measurement.analyse(recording)
    result.rows[0]['time_ratio_measured'] = math.inf
    result.rows[0]['speed_ratio_measured'] = math.nan
    document = report.to_document(result)
    text = json.dumps(document, allow_nan=False)
    assert document['segments'][0]['time_ratio_measured'] is None
    assert json.loads(text)['segments'][0]['speed_ratio_measured'] is None


@pytest.mark.parametrize('case', ['complete', 'incomplete', 'usage', 'bad input', 'output'])
def test_exit_status_policy(tmp_path, capsys, case):
    """0 complete, 1 failure at run time, 2 usage or unusable input, 3 incomplete."""
    path = tmp_path / 'run.mcap'
    write_run(path, PAPER, [0.0, 0.01], hold=3.0, chunk_size=16 * 1024)
    if case == 'usage':
        with pytest.raises(SystemExit) as stop:
            qrm_analyze.main([str(path), '--crank-radius', 'wide'])
        assert stop.value.code == 2
        assert 'argument --crank-radius' in capsys.readouterr().err
        return
    args = {'complete': [path], 'bad input': [tmp_path / 'none.mcap'],
            'output': [path, '--csv', tmp_path / 'no' / 'r.csv']}.get(case)
    if case == 'incomplete':
        cut = tmp_path / 'cut.mcap'
        cut.write_bytes(path.read_bytes()[:-5000])
        args = [cut]
    code, _, err = run_main(args, capsys)
    assert code == {'complete': 0, 'incomplete': 3, 'bad input': 2, 'output': 1}[case], err
    if code in (1, 2):
        assert len(err.strip().splitlines()) == 1 and err.startswith('qrm_analyze: error: ')


@pytest.mark.parametrize('log', sorted(os.listdir(TEST_DATA)))
def test_fast_decoding_gives_what_rosbags_gives_message_by_message(log, monkeypatch):
    if not log.endswith('.mcap'):
        return
    path = os.path.join(TEST_DATA, log)
    fast = recorded_run.read_recording(path)
    monkeypatch.setattr(joint_state_decoding, 'FAST_DECODING', False)
    slow = recorded_run.read_recording(path)
    assert fast.messages_read == slow.messages_read > 0
    for name, values in slow.samples._asdict().items():
        np.testing.assert_array_equal(getattr(fast.samples, name), values, err_msg=name)


def test_figures_of_a_setting_outside_the_closed_form_show_the_measurement_only(tmp_path):
    narrow = kin.Geometry(0.005, PAPER.crank_radius, PAPER.pivot_distance)  # |δ| >= r1 below
    result = measurement.analyse(recorded_run.Recording('odd', narrow, samples_for([0.01]), None))
    (row,) = result.rows
    assert row['time_ratio_theory'] is None and row['time_ratio_measured'] is not None
    assert len(figures.write_figures(result, str(tmp_path))) == len(figures.FIGURES)
