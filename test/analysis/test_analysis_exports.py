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
"""qrm_ros.analysis's front door: its exports are the defining modules' own, loaded on demand."""

import importlib
import subprocess
import sys

import qrm_ros.analysis as analysis

from front_doors import stub_exports


def test_every_exported_name_is_the_object_its_module_defines():
    assert {'analyse', 'format_table', 'read_recording'} <= set(analysis.__all__)
    exported = stub_exports('qrm_ros.analysis')
    assert sorted(analysis.__all__) == sorted(exported)
    for name in analysis.__all__:
        module = importlib.import_module(exported[name])
        assert getattr(analysis, name) is getattr(module, name)


def test_the_package_alone_loads_neither_the_run_reader_nor_matplotlib():
    loaded = subprocess.run(
        [sys.executable, '-c', 'import sys, qrm_ros.analysis; print(sorted(m for m in '
         '("qrm_ros.analysis.recorded_run", "matplotlib", "mcap") if m in sys.modules))'],
        capture_output=True, text=True, check=True).stdout.strip()
    assert loaded == '[]'
