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

import subprocess
import sys


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
