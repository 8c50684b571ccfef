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
The public API users import is typed: mypy checks it (and the code that calls it).

Every module of the typed rooms is checked (found by glob: a new module is checked without
editing this file), every public function and method there says the types of its parameters
and its result, and the installed package says it is typed (PEP 561's ``py.typed``).
"""

import ast
import glob
import importlib.metadata
import os
import subprocess
import sys
from typing import List

import pytest

from repo_paths import REPO_ROOT

PACKAGE = 'qrm_ros'
# The rooms mypy checks, module by module.
TYPED_ROOMS = ['core', 'recording', 'analysis', 'node', 'cli', 'testing']
# The rooms whose public functions and methods must be fully annotated.
ANNOTATED_ROOMS = ['core', 'recording', 'analysis']
TYPED_MARKER = 'py.typed'


def _modules(rooms: List[str]) -> List[str]:
    return sorted(path for room in rooms
                  for path in glob.glob(os.path.join(REPO_ROOT, PACKAGE, room, '*.py')))


def test_mypy_finds_no_type_errors_in_the_typed_rooms():
    pytest.importorskip('mypy')
    paths = _modules(TYPED_ROOMS)
    assert paths, f'no modules found in {TYPED_ROOMS}'
    result = subprocess.run(
        [sys.executable, '-m', 'mypy', '--ignore-missing-imports', '--no-error-summary',
         '--cache-dir', os.path.join(REPO_ROOT, '.mypy_cache'), *paths],
        capture_output=True, text=True, cwd=REPO_ROOT)
    assert result.returncode == 0, result.stdout + result.stderr


def _is_public(name: str) -> bool:
    return not name.startswith('_')


def _missing_annotations(function: ast.FunctionDef, is_method: bool) -> List[str]:
    arguments = function.args
    positional = arguments.posonlyargs + arguments.args
    static = any(isinstance(d, ast.Name) and d.id == 'staticmethod'
                 for d in function.decorator_list)
    if is_method and not static:
        positional = positional[1:]  # self or cls
    parameters = positional + arguments.kwonlyargs + [
        a for a in (arguments.vararg, arguments.kwarg) if a is not None]
    missing = [p.arg for p in parameters if p.annotation is None]
    if function.returns is None:
        missing.append('return')
    return missing


def _public_functions(tree: ast.Module):
    """Yield (qualified name, node, is a method) of the module's public functions and methods."""
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _is_public(node.name):
            yield node.name, node, False
        elif isinstance(node, ast.ClassDef) and _is_public(node.name):
            for member in node.body:
                if (isinstance(member, (ast.FunctionDef, ast.AsyncFunctionDef))
                        and _is_public(member.name)):
                    yield f'{node.name}.{member.name}', member, True


@pytest.mark.parametrize('room', ANNOTATED_ROOMS)
def test_every_public_function_says_its_types(room):
    paths = _modules([room])
    assert paths, f'no modules found in {room}'
    problems = []
    for path in paths:
        with open(path, encoding='utf-8') as handle:
            tree = ast.parse(handle.read(), path)
        for name, function, is_method in _public_functions(tree):
            missing = _missing_annotations(function, is_method)
            if missing:
                problems.append(f'{os.path.relpath(path, REPO_ROOT)}:{function.lineno}: '
                                f'{name} lacks annotations for {", ".join(missing)}')
    assert not problems, '\n'.join(problems)


def test_the_package_says_it_is_typed():
    assert os.path.isfile(os.path.join(REPO_ROOT, PACKAGE, TYPED_MARKER))
    try:
        files = importlib.metadata.files(PACKAGE)
    except importlib.metadata.PackageNotFoundError:
        pytest.skip(f'{PACKAGE} is not installed: nothing to check beyond the source tree')
    if files is None:
        pytest.skip(f'the installed {PACKAGE} does not list its files')
    installed = {str(f).replace(os.sep, '/') for f in files}
    assert f'{PACKAGE}/{TYPED_MARKER}' in installed, \
        f'the installed {PACKAGE} lacks {TYPED_MARKER} (setup.py package_data)'
