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
"""The public API users import is typed: mypy checks it (and the code that calls it)."""

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TYPED_MODULES = ['core/kinematics', 'core/stepping', 'core/strokes', 'core/stroke_monitor',
                 'core/gearbox', 'core/dynamics',
                 'analysis/__init__', 'analysis/animation', 'analysis/design_table',
                 'analysis/figures', 'analysis/gearbox_figure', 'analysis/joint_state_decoding',
                 'analysis/linkage_figure', 'analysis/measurement', 'analysis/plotting',
                 'analysis/recorded_drive', 'analysis/recorded_run', 'analysis/report',
                 'analysis/segments', 'analysis/theory']


def test_mypy_finds_no_type_errors_in_the_public_api():
    pytest.importorskip('mypy')
    paths = [os.path.join(ROOT, 'qrm_ros', f'{name}.py') for name in TYPED_MODULES]
    result = subprocess.run(
        [sys.executable, '-m', 'mypy', '--ignore-missing-imports', '--no-error-summary',
         '--cache-dir', os.path.join(ROOT, '.mypy_cache'), *paths],
        capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
