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
The console scripts' entry points (qrm_ros.cli.entry_points): a stop signal never prints a
traceback, even one that arrives inside a C extension's initialisation.
"""

import os
import signal
import subprocess
import sys

from mcap.reader import make_reader
import pytest
from qrm_ros.cli.exit_codes import EXIT_INTERRUPTED, EXIT_OK, exit_code_for_signal

from ros_probe import installed_executable, wait_for


_STOP_INSIDE_AN_EXTENSION = """
import os, signal, sys, time
class Finder:
    def find_spec(self, name, path=None, target=None):
        if name != 'fake_extension':
            return None
        import importlib.machinery
        return importlib.machinery.ModuleSpec(name, self)
    def create_module(self, spec):
        try:  # a C extension's initialisation, interrupted by the stop signal
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5.0)
        except SystemExit as stop:
            raise ImportError('initialization failed') from stop
    def exec_module(self, module):
        pass
sys.meta_path.insert(0, Finder())
from qrm_ros.cli import entry_points
entry_points.run_command('fake_extension')
print('not stopped')
"""


@pytest.mark.parametrize('node, status', [(False, EXIT_INTERRUPTED), (True, EXIT_OK)],
                         ids=['batch', 'node'])
def test_a_stop_inside_an_extensions_initialisation_is_quiet(node, status):
    """A stop that a C extension's import turns into ImportError exits as a stop, quietly."""
    script = _STOP_INSIDE_AN_EXTENSION.replace(
        'entry_points.run_command', "entry_points.STOP_IS_A_FINISH = ('fake_extension',)\n"
        'entry_points.run_command') if node else _STOP_INSIDE_AN_EXTENSION
    result = subprocess.run([sys.executable, '-c', script],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == status, result.stderr
    assert result.stdout == '' and 'Traceback' not in result.stderr, result.stderr


def _catches(pid, signal_number):
    """Whether the process has a handler of its own for the signal (/proc's SigCgt)."""
    try:
        with open(f'/proc/{pid}/status') as handle:
            caught = next(line for line in handle if line.startswith('SigCgt:'))
    except (FileNotFoundError, StopIteration):
        return False
    return bool(int(caught.split()[1], 16) >> (signal_number - 1) & 1)


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM],
                         ids=['SIGINT', 'SIGTERM'])
def test_a_batch_command_stopped_while_starting_exits_as_stopped(tmp_path, signal_number):
    """qrm_simulate ... && next must not go on: 130 / 143 whenever the stop comes."""
    output = tmp_path / 'run.mcap'
    process = subprocess.Popen([installed_executable('qrm_simulate'), '--duration', '60', '-o',
                                str(output)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    # Its stop handlers are in place from the first moments of its start-up on.
    wait_for(lambda: _catches(process.pid, signal.SIGTERM) or process.poll() is not None,
             30.0, 'the stop handlers of qrm_simulate')
    process.send_signal(signal_number)
    _, err = process.communicate(timeout=60)
    assert process.returncode == exit_code_for_signal(signal_number), err
    assert 'Traceback' not in err
    if output.exists():  # the stop came once it ran: the file is finished, summary and all
        with open(output, 'rb') as stream:
            assert make_reader(stream).get_summary() is not None


_IGNORED_SIGINT = """
import signal, sys
from qrm_ros.cli import entry_points
sys.modules['probe_signals'] = type(sys)('probe_signals')
sys.modules['probe_signals'].main = lambda: print(
    signal.getsignal(signal.SIGINT) is signal.default_int_handler) or 0
raise SystemExit(entry_points.run_command('probe_signals'))
"""


def test_a_command_started_with_sigint_ignored_gets_ctrl_c_back():
    """A script's background job (cmd &) inherits SIGINT ignored; a command stops on it."""
    result = subprocess.run(
        [sys.executable, '-c', _IGNORED_SIGINT], capture_output=True, text=True, timeout=60,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == 'True'


_PROBE = """
import os, sys
from qrm_ros.recording.rosbag2_formats import find_service_definitions
def main():
    print(os.environ['AMENT_PREFIX_PATH'] == sys.prefix)
    print(find_service_definitions('std_srvs/srv/SetBool')[1])
    return 0
"""


def test_a_command_finds_its_environments_ament_index(tmp_path):
    """Run with no ROS install sourced, a command uses the index its ROS wheels installed."""
    (tmp_path / 'probe_ament.py').write_text(_PROBE)
    environment = {name: value for name, value in os.environ.items()
                   if name != 'AMENT_PREFIX_PATH'}
    environment['PYTHONPATH'] = str(tmp_path)
    result = subprocess.run(
        [sys.executable, '-c', 'from qrm_ros.cli import entry_points; '
         'raise SystemExit(entry_points.run_command("probe_ament"))'],
        capture_output=True, text=True, timeout=60, env=environment)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ['True', 'None']  # the service definitions were found


def test_a_command_finds_the_message_definitions_of_its_own_environment(tmp_path):
    """Run without AMENT_PREFIX_PATH (a plain venv, nothing sourced), a command still works."""
    environment = {name: value for name, value in os.environ.items()
                   if name != 'AMENT_PREFIX_PATH'}
    output = tmp_path / 'run.mcap'
    result = subprocess.run([installed_executable('qrm_simulate'), '--duration', '1', '-o',
                             str(output)], capture_output=True, text=True, timeout=120,
                            env=environment)
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr
    with open(output, 'rb') as stream:
        schemas = make_reader(stream).get_summary().schemas.values()
    assert schemas and all(schema.data for schema in schemas)
