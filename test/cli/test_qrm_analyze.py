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
"""qrm_analyze on run files written without ROS: outputs, refusals, damaged files, exit codes."""

import json
import math
import os

import pytest

from qrm_ros.analysis import recorded_run
from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from qrm_ros.analysis import figures
from qrm_ros.analysis import report
from qrm_ros.core.measurement.sampling_bounds import BOUNDED_FIGURES
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from synthetic_run import write_run, write_truncated_run

PAPER = kin.Geometry.paper()
TOLERANCE = (2 * math.pi * 0.01) ** 3


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
    cut = write_truncated_run(tmp_path)
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


def test_an_offset_just_inside_the_coupling_radius_costs_a_bounded_effort_and_says_so(
        tmp_path, capsys):
    # 0.02499999 m with r1 = 0.025 m: the effort theory's round-off floor kept its panels
    # splitting (gigabytes); now it stops at its bound, and says so in the table, the JSON
    # and the exit status rather than growing or printing nothing.
    run = tmp_path / 'singular.mcap'
    write_run(run, kin.Geometry.paper(), [0.02499999], hold=3.0,
              mass=dyn.MassProperties.small_shaper(), loads=dyn.Loads.small_shaper())
    code = qrm_analyze.main([str(run), '--json', str(tmp_path / 'out.json')])
    out, err = capsys.readouterr()
    assert code == exit_codes.EXIT_INCOMPLETE, err
    said = 'the effort integrals cannot be worked out to their tolerance within 20000 panels'
    assert f'theory missing: {said}' in out
    assert 'segment at offset 0.02499999 m' in err and said in err
    row, = json.loads((tmp_path / 'out.json').read_text())['segments']
    assert said in row['effort_theory_problem'] and row['peak_input_torque_theory'] is None


@pytest.mark.parametrize('rate', [10.0, 2.5])
def test_coarse_sampling_is_warned_once_per_figure_and_exits_3(tmp_path, capsys, rate):
    """60 rpm at 10 Hz or 2.5 Hz: figures the sampling cannot support to 1e-3 are said."""
    path = tmp_path / 'coarse.mcap'
    write_run(path, PAPER, [0.01], hold=20.0, rate=rate)
    code, out, err = run_main([path, '--json', tmp_path / 'r.json', '--csv',
                               tmp_path / 'r.csv'], capsys)
    assert code == exit_codes.EXIT_INCOMPLETE, err
    warnings = [line for line in err.splitlines() if 'by the sampling' in line]
    said = [name for name, words in report.FIGURE_WORDS.items()
            if any(line.split(': warning: ')[1].startswith(words + ' is not') for line in
                   warnings)]
    assert len(said) == len(warnings) >= 3  # one line per kind of figure
    assert 'time_ratio' in said and 'peak_speed_ratio' in said
    assert 'sampling' in out.splitlines()[3]
    (segment,) = json.loads((tmp_path / 'r.json').read_text())['segments']
    header = (tmp_path / 'r.csv').read_text().splitlines()[0].split(',')
    for name in BOUNDED_FIGURES:
        assert f'{name}_sampling_bound' in segment and f'{name}_sampling_bound' in header
        bound = segment[f'{name}_sampling_bound']
        measured, theory = segment[f'{name}_measured'], segment[f'{name}_theory']
        if bound is not None and measured is not None:
            assert abs(measured - theory) <= bound + 1e-9 * abs(theory)


def test_fine_sampling_supports_every_figure(tmp_path, capsys):
    path = tmp_path / 'fine.mcap'
    write_run(path, PAPER, [-0.015, 0.015], hold=4.0, rate=100.0)
    code, out, err = run_main([path, '--json', tmp_path / 'r.json'], capsys)
    assert code == exit_codes.EXIT_OK and 'sampling' not in err, err
    for segment in json.loads((tmp_path / 'r.json').read_text())['segments']:
        for name in BOUNDED_FIGURES:
            assert segment[f'{name}_sampling_bound'] < 1e-3 * abs(segment[f'{name}_theory'])
