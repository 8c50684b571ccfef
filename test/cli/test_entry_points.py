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
import subprocess
import sys

from mcap.reader import make_reader

from ros_probe import installed_executable


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


def test_a_stop_inside_an_extensions_initialisation_is_quiet():
    """A stop that a C extension's import turns into ImportError still exits 0, quietly."""
    result = subprocess.run([sys.executable, '-c', _STOP_INSIDE_AN_EXTENSION],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout == '' and 'Traceback' not in result.stderr, result.stderr


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
