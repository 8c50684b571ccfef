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
"""The package as colcon and rosdep see it: an ament_python package whose keys all resolve.

rosdep's database cannot be read here (no network in CI), so the keys it lacks are checked
against the repository's own rosdep file, and that file against what the venv installs.
"""

import os
import xml.etree.ElementTree as ElementTree

import pytest
import yaml
from repo_paths import REPO_ROOT

ROSDEP_FILE = os.path.join(REPO_ROOT, 'rosdep', 'qrm_ros.yaml')


def _package_xml() -> ElementTree.Element:
    return ElementTree.parse(os.path.join(REPO_ROOT, 'package.xml')).getroot()


def _dependency_keys() -> set:
    root = _package_xml()
    return {element.text for tag in ('depend', 'exec_depend', 'test_depend', 'build_depend')
            for element in root.iter(tag)}


def _pinned_requirements() -> set:
    with open(os.path.join(REPO_ROOT, 'requirements.txt'), encoding='utf-8') as stream:
        lines = [line.split('#')[0].strip() for line in stream]
    return {line.split('==')[0].split('[')[0].lower() for line in lines if '==' in line}


def _rosdep_rules() -> dict:
    with open(ROSDEP_FILE, encoding='utf-8') as stream:
        return yaml.safe_load(stream)


def test_ament_python_package_format_3():
    root = _package_xml()
    assert root.tag == 'package' and root.get('format') == '3'
    assert root.find('name').text == 'qrm_ros'
    assert root.find('export/build_type').text == 'ament_python'
    assert os.path.isfile(os.path.join(REPO_ROOT, 'resource', 'qrm_ros'))
    with open(os.path.join(REPO_ROOT, 'setup.cfg'), encoding='utf-8') as stream:
        text = stream.read()
    assert 'script_dir=$base/lib/qrm_ros' in text
    assert 'install_scripts=$base/lib/qrm_ros' in text


def test_every_key_of_the_rosdep_file_is_used_by_package_xml():
    assert set(_rosdep_rules()) <= _dependency_keys()


@pytest.mark.parametrize('key', sorted(_rosdep_rules()))
def test_rosdep_file_key_installs_what_the_venv_pins(key):
    """A key resolves on the systems ROS 2 Jazzy supports, to a package requirements.txt pins."""
    rules = _rosdep_rules()[key]
    assert {'ubuntu', 'debian'} <= set(rules)
    pinned = _pinned_requirements()
    for system, rule in rules.items():
        if isinstance(rule, dict):
            packages = rule['pip']['packages']
            assert all(package.lower() in pinned for package in packages), (system, packages)
        else:  # a system package: the same Python distribution under Debian's name
            assert rule == [key], (system, rule)
