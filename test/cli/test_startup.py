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
A command loads only what it uses: its start-up imports none of the heavy libraries it needs not.

The recorder records bytes (no scipy, numba or matplotlib); the analysis draws only when asked
(matplotlib is loaded by the drawing, not by the command's import). Each command's module is
imported in a fresh interpreter under ``-X importtime``, whose report also names who imported
a library that should not be there.
"""

import os
import subprocess
import sys
from typing import Dict, List, Tuple

import pytest

from repo_paths import REPO_ROOT

# The module each console script runs, and the libraries importing it must not load.
COMMANDS = {
    'mcap_recorder': ('qrm_ros.cli.mcap_recorder', ['scipy', 'numba', 'matplotlib']),
    'qrm_analyze': ('qrm_ros.cli.qrm_analyze', ['matplotlib']),
    'qrm_bridge': ('qrm_ros.cli.qrm_bridge', ['scipy', 'numba', 'matplotlib']),
}


def _import_report(module: str) -> List[Tuple[int, str]]:
    """Return (depth, module) per line of ``-X importtime``, in its order (children first)."""
    result = subprocess.run([sys.executable, '-X', 'importtime', '-c', f'import {module}'],
                            capture_output=True, text=True, cwd=REPO_ROOT)
    assert result.returncode == 0, result.stderr[-4000:]
    report = []
    for line in result.stderr.splitlines():
        if line.startswith('import time:') and '|' in line:
            name = line.rsplit('|', 1)[1]
            stripped = name.lstrip()
            if stripped and stripped != 'imported package':
                report.append(((len(name) - len(stripped)) // 2, stripped))
    return report


def _importers(report: List[Tuple[int, str]], position: int, library: str) -> List[str]:
    """The chain of imports that first loaded `library` (at `position`), outermost first."""
    depth, name = report[position]
    chain = [name]
    for outer_depth, outer in report[position + 1:]:
        if outer_depth < depth:
            chain.append(outer)
            depth = outer_depth
    chain.reverse()
    first_of_library = next(i for i, n in enumerate(chain) if n.split('.')[0] == library)
    return chain[:first_of_library + 1]


@pytest.mark.parametrize('command', sorted(COMMANDS))
def test_a_command_loads_only_what_it_uses(command):
    module, unwanted = COMMANDS[command]
    path = os.path.join(REPO_ROOT, *module.split('.')) + '.py'
    if not os.path.isfile(path):
        pytest.skip(f'{module} does not exist yet (its command still runs from a model '
                    'module); remove this skip once the command lives in qrm_ros/cli/')
    report = _import_report(module)
    first: Dict[str, int] = {}
    for position, (_, name) in enumerate(report):
        top = name.split('.')[0]
        if top in unwanted:
            first.setdefault(top, position)  # the first line is the deepest: the culprit's
    loaded = [f'{library}, imported through {" -> ".join(_importers(report, position, library))}'
              for library, position in sorted(first.items())]
    assert not loaded, f'{command} ({module}) loads at start-up:\n  ' + '\n  '.join(loaded)
