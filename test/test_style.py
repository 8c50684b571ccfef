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
"""Style gates that ament_flake8 / ament_pep257 / ament_copyright would apply under colcon."""

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOURCE_FOLDERS = ['qrm_ros', 'test', 'bench', 'launch', 'doc']
LICENSE_LINES = [
    '# Copyright 20',
    '# Licensed under the Apache License, Version 2.0',
]


def _python_files():
    files = [os.path.join(ROOT, 'setup.py'), os.path.join(ROOT, 'dev.py')]
    for folder in SOURCE_FOLDERS:
        for base, _, names in os.walk(os.path.join(ROOT, folder)):
            files += [os.path.join(base, n) for n in sorted(names) if n.endswith('.py')]
    return files


def test_flake8():
    result = subprocess.run([sys.executable, '-m', 'flake8', '--config',
                             os.path.join(ROOT, 'setup.cfg')] + _python_files(),
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_pep257():
    pydocstyle = pytest.importorskip('pydocstyle')
    del pydocstyle
    result = subprocess.run([sys.executable, '-m', 'pydocstyle', '--config',
                             os.path.join(ROOT, 'setup.cfg')] + _python_files(),
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize('path', _python_files(), ids=lambda p: os.path.relpath(p, ROOT))
def test_license_header(path):
    with open(path) as handle:
        head = handle.read(2000)
    for line in LICENSE_LINES:
        assert line in head, f'{path} lacks the license header line {line!r}'
