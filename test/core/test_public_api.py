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
"""qrm_ros.core's front doors: every exported name is the defining module's, loaded on demand."""

import importlib
import pkgutil
import subprocess
import sys

import pytest

import qrm_ros.core as core

from front_doors import stub_exports

# The core's front door, and its two parts whose names a script takes as a module
# (``kin.time_ratio``, ``dyn.Loads``).
FRONT_DOORS = ['qrm_ros.core', 'qrm_ros.core.kinematics', 'qrm_ros.core.dynamics']


@pytest.mark.parametrize('package', FRONT_DOORS)
def test_every_exported_name_is_the_object_its_module_defines(package):
    door = importlib.import_module(package)
    exported = stub_exports(package)
    assert door.__all__, f'{package} exports nothing'
    assert sorted(door.__all__) == sorted(exported)
    for name in door.__all__:
        module = importlib.import_module(exported[name])
        assert name in getattr(module, '__all__', ()), f'{name} is not public in {module}'
        assert getattr(door, name) is getattr(module, name)


@pytest.mark.parametrize('package', FRONT_DOORS)
def test_no_exported_name_is_also_a_module_of_the_package(package):
    # Importing a submodule binds its name on the package, hiding an export of that name.
    door = importlib.import_module(package)
    modules = {module.name for module in pkgutil.iter_modules(door.__path__)}
    assert not modules & set(door.__all__)


def test_star_import_gives_the_same_names():
    namespace = {}
    exec('from qrm_ros.core import *', namespace)
    assert set(core.__all__) <= set(namespace)


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match='no_such_name'):
        core.no_such_name


def test_the_package_alone_loads_neither_scipy_nor_numba():
    loaded = subprocess.run(
        [sys.executable, '-c', 'import sys, qrm_ros.core, qrm_ros.core.kinematics.geometry; '
         'print(sorted(m for m in ("scipy", "numba", "matplotlib") if m in sys.modules))'],
        capture_output=True, text=True, check=True).stdout.strip()
    assert loaded == '[]'
