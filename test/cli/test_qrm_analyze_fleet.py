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
``qrm_analyze`` on a fleet: several runs and folders, a local pool, a Dask cluster, Ctrl-C.

The fleet report must be the same bit for bit whether the files are analysed one after the
other, in a pool of local processes or on a real ``distributed.LocalCluster`` (scheduler and
workers as processes on loopback); each file's results the same as ``--json``/``--csv`` of
that file alone; a damaged file is reported in its row and sets the exit status without
stopping the others; Ctrl-C stops every worker.
"""

import contextlib
import glob
import io
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

from qrm_ros.analysis import dask_scheduler
from qrm_ros.analysis import fleet
from qrm_ros.analysis import fleet_figure
from qrm_ros.analysis import streamed_run
from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from qrm_ros.core.kinematics.geometry import Geometry
from repo_paths import TEST_DATA
from synthetic_run import write_run, write_truncated_run

GOLDEN = sorted(glob.glob(os.path.join(TEST_DATA, '*.mcap')))
# The motor log is complete, but its efforts have no sampling bound (the motor's steady
# running is simulated, not in closed form): exit 3 for that alone, 'incomplete' in a fleet.
UNSUPPORTED = [path for path in GOLDEN if 'motor' in os.path.basename(path)]


def expected_code(paths):
    """The exit status of qrm_analyze on these golden logs: 3 if the motor log is there."""
    return (exit_codes.EXIT_INCOMPLETE if set(paths) & set(UNSUPPORTED)
            else exit_codes.EXIT_OK)


def run_main(args, capsys):
    code = qrm_analyze.main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert 'Traceback' not in err
    return code, out, err


@pytest.fixture
def fleet_folder(tmp_path):
    """The golden logs in a folder tree, with a file that is not a run and a cut-short run."""
    folder = tmp_path / 'fleet'
    (folder / 'machine_b').mkdir(parents=True)
    for index, path in enumerate(GOLDEN):
        target = folder / ('machine_b' if index % 2 else '') / os.path.basename(path)
        shutil.copy(path, target)
    (folder / 'machine_b' / 'not_a_run.mcap').write_bytes(b'garbage, not MCAP')
    (folder / 'notes.txt').write_text('not searched')
    return folder


def test_a_fleet_gives_the_same_report_serially_in_a_pool_and_on_a_dask_cluster(
        fleet_folder, tmp_path, capsys):
    reports = {}
    for mode, options in (('serial', ['--jobs', '1']), ('pool', ['--jobs', '2'])):
        out_dir = tmp_path / mode
        code, out, err = run_main([fleet_folder, '--output-dir', out_dir, *options], capsys)
        assert code == exit_codes.EXIT_BAD_INPUT, err  # the worst file: one is not MCAP
        reports[mode] = out_dir
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host='127.0.0.1',
                      dashboard_address=None) as cluster:
        out_dir = tmp_path / 'dask'
        code, out, err = run_main([fleet_folder, '--output-dir', out_dir, '--scheduler',
                                   cluster.scheduler_address], capsys)
        assert code == exit_codes.EXIT_BAD_INPUT, err
        reports['dask'] = out_dir
    serial = (reports['serial'] / 'fleet.json').read_bytes()
    for mode in ('pool', 'dask'):
        assert (reports[mode] / 'fleet.json').read_bytes() == serial, mode
        assert (reports[mode] / 'fleet.csv').read_bytes() == (
            reports['serial'] / 'fleet.csv').read_bytes(), mode
    document = json.loads(serial)
    rows = {os.path.basename(row['file']): row for row in document['recordings']}
    assert len(rows) == len(GOLDEN) + 1 and 'notes.txt' not in rows
    bad = rows['not_a_run.mcap']
    assert bad['status'] == 'refused' and 'not an MCAP file' in bad['problem']
    assert bad['segments'] is None
    for path in GOLDEN:
        row = rows[os.path.basename(path)]
        if path in UNSUPPORTED:
            assert row['status'] == 'incomplete' and 'by the sampling' in row['problem']
        else:
            assert row['status'] == 'complete' and row['problem'] is None
        stem = os.path.basename(path)[:-5]
        written = json.loads((reports['serial'] / stem / 'results.json').read_text())
        assert row['segments'] == len(written['segments'])
        assert row['stroke_pairs'] == sum(s['stroke_pairs'] for s in written['segments'])
        assert row['crank_radius'] == written['geometry']['crank_radius']
        errors = [s['time_ratio_relative_error'] for s in written['segments']
                  if s['time_ratio_relative_error'] is not None]
        assert row['worst_time_ratio_error'] == max(errors, key=abs)
    assert (reports['serial'] / 'fleet_time_ratio_error.png').stat().st_size > 0
    assert document['status'] == {'complete': len(GOLDEN) - len(UNSUPPORTED),
                                  'incomplete': len(UNSUPPORTED), 'refused': 1, 'failed': 0}


def test_a_single_threaded_process_forks_its_workers_any_other_spawns_them():
    probe = ('import sys, threading, time\n'
             'from qrm_ros.analysis import fleet\n'
             'print(fleet.start_method())\n'
             'if sys.argv[1] == "thread":\n'
             '    threading.Thread(target=time.sleep, args=(5,), daemon=True).start()\n'
             'else:\n'
             '    import rclpy  # noqa: F401 - DDS may run threads of its own\n'
             'print(fleet.start_method())\n')
    for other in ('thread', 'ros'):
        done = subprocess.run([sys.executable, '-c', probe, other], capture_output=True,
                              text=True, check=True)
        assert done.stdout.split() == ['fork', 'spawn'], other


def test_forked_and_spawned_workers_give_the_same_fleet_report(fleet_folder, tmp_path,
                                                               capsys, monkeypatch):
    reports = []
    for method in ('fork', 'spawn'):
        monkeypatch.setattr(fleet, 'start_method', lambda chosen=method: chosen)
        code, _, err = run_main([fleet_folder, '--output-dir', tmp_path / method, '--jobs', '2'],
                                capsys)
        assert code == exit_codes.EXIT_BAD_INPUT, err  # the worst file: one is not MCAP
        reports.append((tmp_path / method / 'fleet.json').read_bytes())
    assert reports[0] == reports[1]


def test_each_runs_results_are_those_of_the_run_alone(fleet_folder, tmp_path, capsys):
    out_dir = tmp_path / 'out'
    run_main([*GOLDEN[:2], '--output-dir', out_dir, '--jobs', '2'], capsys)
    for path in GOLDEN[:2]:
        alone = tmp_path / 'alone'
        code, _, _ = run_main([path, '--json', alone.with_suffix('.json'), '--csv',
                               alone.with_suffix('.csv')], capsys)
        assert code == expected_code([path])
        stem = os.path.basename(path)[:-5]
        assert (out_dir / stem / 'results.json').read_bytes() == alone.with_suffix(
            '.json').read_bytes()
        assert (out_dir / stem / 'results.csv').read_bytes() == alone.with_suffix(
            '.csv').read_bytes()


def test_an_incomplete_run_sets_the_status_without_stopping_the_others(tmp_path, capsys):
    cut = write_truncated_run(tmp_path)
    out_dir = tmp_path / 'out'
    code, out, err = run_main([cut, GOLDEN[1], '--jobs', '2', '--output-dir', out_dir], capsys)
    assert code == exit_codes.EXIT_INCOMPLETE, err
    rows = {os.path.basename(row['file']): row for row in json.loads(
        (out_dir / 'fleet.json').read_text())['recordings']}
    assert rows['cut.mcap']['status'] == 'incomplete'
    assert 'was not finished' in rows['cut.mcap']['problem']
    assert rows['cut.mcap']['segments'] >= 1
    assert rows[os.path.basename(GOLDEN[1])]['status'] == 'complete'
    assert 'qrm_analyze: warning: ' in err and 'cut.mcap' in err


@pytest.mark.parametrize('options, expected', [
    (['--csv', 'x.csv'], '--csv take one run'),
    (['--jobs', '0'], '--jobs must be a whole number of processes >= 1, got 0'),
    (['--scheduler', 'localhost'], '--scheduler must be a Dask scheduler address'),
    (['--jobs', '2', '--scheduler', 'tcp://127.0.0.1:1'], '--jobs is for local processes'),
])
def test_bad_fleet_options_are_refused_in_one_line(options, expected, tmp_path, capsys):
    code, out, err = run_main([*GOLDEN[:2], *options], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert err.strip() == f'qrm_analyze: error: {err.strip()[20:]}'
    assert expected in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize('address, expected', [
    ('tcp://127.0.0.1:99999', "--scheduler 'tcp://127.0.0.1:99999': the port must be in 1-65535"),
    ('tcp://:8786', "--scheduler 'tcp://:8786' names no host (tcp://HOST:PORT)"),
    ('http://127.0.0.1:8786', '--scheduler must be a Dask scheduler address such as'),
    ('tcp://no-such-host.invalid:8786', "the scheduler host 'no-such-host.invalid' does not "
     'resolve'),
])
def test_a_scheduler_address_that_cannot_be_one_is_refused_at_once(address, expected, capsys):
    started = time.monotonic()
    code, _, err = run_main([*GOLDEN[:2], '--scheduler', address], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT, err
    assert err.strip().splitlines() == [err.strip()] and expected in err
    assert time.monotonic() - started < 10.0  # not Dask's 20 s connection time-out


class _FakeScheduler:
    """A TCP server on loopback that is no Dask scheduler: it sends junk, or says nothing."""

    def __init__(self, junk):
        self.server = socket.create_server(('127.0.0.1', 0))
        self.address = 'tcp://127.0.0.1:%d' % self.server.getsockname()[1]
        self.junk, self.connections = junk, []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        with contextlib.suppress(OSError):
            while True:
                connection, _ = self.server.accept()
                self.connections.append(connection)
                if self.junk:
                    connection.sendall(b'\xff' * 64)

    def close(self):
        self.server.close()
        for connection in self.connections:
            connection.close()


@pytest.mark.parametrize('junk, expected', [
    (True, 'does not answer as a Dask scheduler (ValueError'),
    (False, 'accepted the connection but no Dask scheduler answered within 2 s'),
], ids=['junk', 'silent'])
def test_a_server_that_is_no_scheduler_is_said_and_blames_no_run(junk, expected, capsys,
                                                                 monkeypatch):
    monkeypatch.setattr(dask_scheduler, 'SCHEDULER_TIMEOUT', 2.0)
    fake = _FakeScheduler(junk)
    try:
        code, _, err = run_main([*GOLDEN[:2], '--scheduler', fake.address], capsys)
    finally:
        fake.close()
    assert code == exit_codes.EXIT_BAD_INPUT, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f'qrm_analyze: error: {fake.address} {expected}'), err
    assert '.mcap' not in lines[0]


def test_nothing_listening_is_said(capsys):
    with socket.create_server(('127.0.0.1', 0)) as placeholder:
        port = placeholder.getsockname()[1]  # free once closed: nothing listens there
    code, _, err = run_main([*GOLDEN[:2], '--scheduler', f'tcp://127.0.0.1:{port}'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT
    assert err.strip() == (f'qrm_analyze: error: nothing answers at tcp://127.0.0.1:{port} '
                           '(Connection refused)')


def test_a_folder_without_runs_is_refused(tmp_path, capsys):
    code, _, err = run_main([tmp_path, '--jobs', '1'], capsys)
    assert code == exit_codes.EXIT_BAD_INPUT and 'no .mcap files in' in err


def _children(pid):
    try:
        with open(f'/proc/{pid}/task/{pid}/children') as handle:
            return [int(child) for child in handle.read().split()]
    except FileNotFoundError:
        return []


def _alive(pid):
    try:
        with open(f'/proc/{pid}/stat') as handle:
            return handle.read().split(')')[-1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM],
                         ids=['SIGINT', 'SIGTERM'])
def test_a_stop_signal_stops_every_worker(tmp_path, signal_number):
    folder = tmp_path / 'many'
    folder.mkdir()
    for copy in range(12):
        shutil.copy(GOLDEN[copy % len(GOLDEN)], folder / f'run{copy:02d}.mcap')
    command = subprocess.Popen([sys.executable, '-m', 'qrm_ros.cli.qrm_analyze', str(folder),
                                '--jobs', '2', '--output-dir', str(tmp_path / 'out')],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60.0
    workers = []
    while time.monotonic() < deadline and len(workers) < 2:
        workers = _children(command.pid)
        time.sleep(0.05)
    assert len(workers) >= 2, 'the pool never started'
    command.send_signal(signal_number)
    _, err = command.communicate(timeout=60.0)
    assert command.returncode == exit_codes.exit_code_for_signal(signal_number), err
    assert 'Traceback' not in err and 'interrupted' in err
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in workers)
    assert not (tmp_path / 'out' / 'fleet.json').exists()


def test_ctrl_c_cancels_the_fleet_on_a_dask_cluster(tmp_path):
    from distributed import Client, LocalCluster
    folder = tmp_path / 'many'
    folder.mkdir()
    for copy in range(24):
        shutil.copy(GOLDEN[copy % len(GOLDEN)], folder / f'run{copy:02d}.mcap')
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host='127.0.0.1',
                      dashboard_address=None) as cluster, Client(cluster) as observer:
        command = subprocess.Popen(
            [sys.executable, '-m', 'qrm_ros.cli.qrm_analyze', str(folder), '--scheduler',
             cluster.scheduler_address], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True)
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not any(observer.processing().values()):
            time.sleep(0.05)
        assert any(observer.processing().values()), 'no task ever reached a worker'
        command.send_signal(signal.SIGINT)
        _, err = command.communicate(timeout=60.0)
        assert command.returncode == exit_codes.EXIT_INTERRUPTED, err
        assert 'Traceback' not in err and 'interrupted' in err
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and any(observer.processing().values()):
            time.sleep(0.05)
        assert not any(observer.processing().values()), 'tasks still running'
        assert len(observer.scheduler_info()['workers']) == 2  # the cluster itself goes on


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_one_progress_bar_over_the_files_on_a_terminal(tmp_path, monkeypatch):
    terminal = Terminal()
    monkeypatch.setattr(sys, 'stderr', terminal)
    monkeypatch.setattr(streamed_run, 'PROGRESS_MIN_MESSAGES', 1)  # a file's own bar if any
    code = qrm_analyze.main([*GOLDEN[:3], '--jobs', '1'])
    assert code == expected_code(GOLDEN[:3]), terminal.getvalue()
    shown = terminal.getvalue()
    counts = re.findall(r'analysing: +\d+%\|[^|]*\| (\d+)/(\d+) ', shown)
    assert counts and {total for _, total in counts} == {'3'}  # the files, counted
    assert 'reading joint states' not in shown  # no file draws its own bar


def test_the_fleet_figure_draws_each_segments_time_ratio_error(tmp_path, capsys, monkeypatch):
    figures = []
    close = fleet_figure.plt.close

    def kept(figure):
        figures.append(figure)
        close(figure)
    monkeypatch.setattr(fleet_figure.plt, 'close', kept)
    out_dir = tmp_path / 'out'
    code, _, err = run_main([*GOLDEN, '--output-dir', out_dir, '--jobs', '1'], capsys)
    assert code == expected_code(GOLDEN), err
    (figure,) = figures
    drawn = {line.get_label(): (list(line.get_xdata()), list(line.get_ydata()))
             for line in figure.axes[0].get_lines() if line.get_gid() == 'recording'}
    expected = {}
    for path in GOLDEN:  # each run's own results.json, written beside the figure
        segments = json.loads((out_dir / os.path.basename(path)[:-5] / 'results.json')
                              .read_text())['segments']
        measured = [s for s in segments if s['time_ratio_relative_error'] is not None]
        if measured:
            expected[os.path.basename(path)] = (
                [s['offset_over_pivot_distance'] for s in measured],
                [s['time_ratio_relative_error'] for s in measured])
    assert drawn == expected and len(drawn) >= 2


def test_a_run_whose_figures_the_sampling_cannot_support_is_incomplete_in_the_fleet(
        tmp_path, capsys):
    """The fleet's status is the single file's exit rule (report.shortfalls), not losses only."""
    coarse = tmp_path / 'coarse.mcap'
    write_run(coarse, Geometry.paper(), [0.01], hold=20.0, rate=10.0)
    alone, _, _ = run_main([coarse], capsys)
    out_dir = tmp_path / 'out'
    code, out, err = run_main([coarse, GOLDEN[1], '--jobs', '1', '--output-dir', out_dir],
                              capsys)
    assert alone == code == exit_codes.EXIT_INCOMPLETE, err
    rows = {os.path.basename(row['file']): row for row in json.loads(
        (out_dir / 'fleet.json').read_text())['recordings']}
    assert rows['coarse.mcap']['status'] == 'incomplete'
    assert 'not supported to 0.001 by the sampling' in rows['coarse.mcap']['problem']
    assert rows['coarse.mcap']['lost_messages'] == 0
    assert rows[os.path.basename(GOLDEN[1])]['status'] == 'complete'
    assert 'by the sampling' in err
