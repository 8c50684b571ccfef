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
The house's rules, read from the source with ``ast``: a newcomer finds things where they belong.

Rooms are the sub-packages of qrm_ros; imports run one way (cli -> analysis / node ->
recording -> core). The two big rooms, core and node, are made of parts (their
sub-packages), which import one way too. Commands live in cli, modules, classes and parts
stay small enough to read, and nothing points outside the repository.
"""

import ast
import functools
import os
import subprocess
from typing import Dict, Iterator, List, NamedTuple, Optional, Set, Tuple

from repo_paths import REPO_ROOT

PACKAGE = 'qrm_ros'
PACKAGE_FOLDER = os.path.join(REPO_ROOT, PACKAGE)
# The rooms each room may import from (itself included): imports run one way.
ALLOWED_IMPORTS = {
    # The test kit for users' suites starts nodes and reads runs, as a user's test would.
    'testing': {'testing', 'node', 'recording', 'core'},
    'cli': {'cli', 'analysis', 'node', 'recording', 'core'},
    'analysis': {'analysis', 'recording', 'core'},
    'node': {'node', 'recording', 'core'},
    'recording': {'recording', 'core'},
    'core': {'core'},
}
# The parts of the rooms that have them, and the parts each may import from (itself
# included), bottom up. Every module of such a room sits in one of its parts.
_CORE_BELOW_MOTOR = {'stepping', 'dynamics', 'kinematics', 'numerics', 'common'}
PART_IMPORTS = {
    'core': {
        'common': {'common'},
        'numerics': {'numerics', 'common'},
        'kinematics': {'kinematics', 'numerics', 'common'},
        'dynamics': {'dynamics', 'kinematics', 'numerics', 'common'},
        'stepping': {'stepping', 'dynamics', 'kinematics', 'numerics', 'common'},
        'motor': {'motor'} | _CORE_BELOW_MOTOR,
        'measurement': {'measurement', 'motor'} | _CORE_BELOW_MOTOR,
        'design': {'design', 'motor'} | _CORE_BELOW_MOTOR,
    },
    'node': {
        'process': {'process'},
        'shaper_sim': {'shaper_sim', 'process'},
        'recorder': {'recorder', 'process'},
        'player': {'player', 'process'},
        'bridge': {'bridge', 'recorder', 'process'},  # the recorder's message forms
        'offline': {'offline', 'shaper_sim', 'recorder', 'process'},
        'main_job': {'main_job', 'process'},
    },
}
MAX_PART_MODULES = 12
# The only qrm_ros modules that may be imported inside a function, and why: each defers a
# heavy optional dependency to the moment it is needed.
DEFERRED_IMPORTS = {
    'qrm_ros.core.kinematics.peak_kernel':
        'numba kernels: compiled only when a peak is searched',
    'qrm_ros.core.dynamics.torque_kernel':
        'numba kernels: compiled only when torques are computed',
    'qrm_ros.core.dynamics.drive_kernel':
        'numba kernels: loaded only for a motor or an offline run',
    'qrm_ros.core.numerics.portable_math_kernel':
        'numba kernels: compiled only for large arrays',
    'qrm_ros.analysis.figures': 'matplotlib: loaded only by a command that draws',
    'qrm_ros.analysis.gearbox_figure': 'matplotlib: loaded only by a command that draws',
    'qrm_ros.analysis.animation': 'matplotlib: loaded only by a command that animates',
    'qrm_ros.analysis.animation_window': 'matplotlib: loaded only by a command that animates',
    'qrm_ros.analysis.fleet_figure': 'matplotlib: loaded only when a fleet report is written',
}
MAX_MODULE_LINES = 600
MAX_CLASS_LINES = 300
COMMAND_ROOM = 'cli'
# Paths to notes outside the repository (spelled in pieces so this file does not name them).
OUTSIDE_PATHS = ['..' + '/shared', 'shared' + '/design', 'shared' + '/reference']
# Folders a checkout without git may hold that are not part of the repository.
NOT_IN_REPOSITORY = {'.git', '.venv', '.mypy_cache', '.pytest_cache', '__pycache__', 'build',
                     'install', 'log', 'runs'}


class Module(NamedTuple):
    """One source module of qrm_ros, parsed."""

    name: str  # dotted, e.g. 'qrm_ros.core.kinematics'
    path: str  # relative to the repository
    room: Optional[str]  # 'core', 'node', ...; None for the package's own __init__
    lines: int
    tree: ast.Module


class Import(NamedTuple):
    """One qrm_ros module (and the names taken from it) imported by a statement."""

    module: str
    names: Tuple[str, ...]
    line: int
    in_function: bool


def _module_name(relative_path: str) -> str:
    parts = relative_path[:-len('.py')].split(os.sep)
    if parts[-1] == '__init__':
        parts = parts[:-1]
    return '.'.join(parts)


def _read_modules() -> List[Module]:
    modules = []
    for base, folders, names in os.walk(PACKAGE_FOLDER):
        folders[:] = sorted(f for f in folders if f != '__pycache__')
        for name in sorted(n for n in names if n.endswith('.py')):
            path = os.path.relpath(os.path.join(base, name), REPO_ROOT)
            with open(os.path.join(REPO_ROOT, path), encoding='utf-8') as handle:
                text = handle.read()
            dotted = _module_name(path)
            parts = dotted.split('.')
            modules.append(Module(dotted, path, parts[1] if len(parts) > 1 else None,
                                  len(text.splitlines()), ast.parse(text, path)))
    return modules


MODULES = _read_modules()
MODULE_NAMES = {m.name for m in MODULES}


def _resolve(module: Module, node: ast.ImportFrom) -> str:
    """The absolute module a ``from`` import names (relative imports resolved)."""
    if not node.level:
        return node.module or ''
    package = module.name.split('.')
    if not module.path.endswith('__init__.py'):
        package = package[:-1]
    base = package[:len(package) - node.level + 1]
    return '.'.join(base + ([node.module] if node.module else []))


@functools.lru_cache(maxsize=None)
def _imports(module: Module) -> Tuple[Import, ...]:
    """Every import of a qrm_ros module in `module`, marked when inside a function."""
    def walk(node: ast.AST, in_function: bool) -> Iterator[Import]:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                       ast.Lambda))
            if isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name.split('.')[0] == PACKAGE:
                        yield Import(alias.name, (), child.lineno, in_function)
            elif isinstance(child, ast.ImportFrom):
                source = _resolve(module, child)
                if source.split('.')[0] != PACKAGE:
                    continue
                names = tuple(alias.name for alias in child.names)
                # `from qrm_ros.core import kinematics` imports the module qrm_ros.core.kinematics
                submodules = [f'{source}.{n}' for n in names if f'{source}.{n}' in MODULE_NAMES]
                for imported in submodules or [source]:
                    yield Import(imported, () if submodules else names, child.lineno,
                                 in_function)
            yield from walk(child, inside)
    return tuple(walk(module.tree, False))


@functools.lru_cache(maxsize=None)
def _nodes(module: Module) -> Tuple[ast.AST, ...]:
    """Every node of the module's syntax tree (walked once, read by several rules)."""
    return tuple(ast.walk(module.tree))


def _room_of(module_name: str) -> Optional[str]:
    parts = module_name.split('.')
    return parts[1] if len(parts) > 1 else None


def _is_private(name: str) -> bool:
    return name.startswith('_') and not (name.startswith('__') and name.endswith('__'))


def _report(problems: List[str], rule: str) -> str:
    return f'{len(problems)} breaches of "{rule}":\n  ' + '\n  '.join(problems)


# --- (a) imports run one way ---------------------------------------------------------------

def test_imports_run_one_way():
    problems = []
    for module in MODULES:
        if module.room is None:
            continue
        allowed = ALLOWED_IMPORTS.get(module.room)
        assert allowed is not None, f'{module.path}: room {module.room!r} has no import rule'
        for imported in _imports(module):
            room = _room_of(imported.module)
            if room not in allowed:
                problems.append(f'{module.path}:{imported.line}: {module.room} imports '
                                f'{imported.module} ({room})')
    assert not problems, _report(problems, 'cli -> analysis / node -> recording -> core')


def test_the_package_itself_imports_no_room():
    # `import qrm_ros` must stay cheap and must not tie the rooms together.
    package = next(m for m in MODULES if m.room is None)
    imported = [f'{package.path}:{i.line}: {i.module}' for i in _imports(package)]
    assert not imported, _report(imported, 'qrm_ros/__init__.py imports no room')


def _part_of(module_name: str) -> Optional[str]:
    """The part of a room with parts that a module sits in (None: the room's own __init__)."""
    parts = module_name.split('.')
    return parts[2] if len(parts) > 2 and parts[1] in PART_IMPORTS else None


def test_every_module_of_a_room_with_parts_sits_in_a_part():
    problems = [f'{m.path}: in no part of {m.room} ({", ".join(PART_IMPORTS[m.room])})'
                for m in MODULES if m.room in PART_IMPORTS and m.name != f'{PACKAGE}.{m.room}'
                and _part_of(m.name) not in PART_IMPORTS[m.room]]
    assert not problems, _report(problems, 'every module in a part')


def test_parts_import_one_way():
    problems = []
    for module in MODULES:
        part = _part_of(module.name)
        if part is None:
            continue
        allowed = PART_IMPORTS[module.room][part]
        for imported in _imports(module):
            if _room_of(imported.module) != module.room:
                continue
            target = _part_of(imported.module)
            if target not in allowed:
                where = "the room's front door" if target is None else target
                problems.append(f'{module.path}:{imported.line}: {module.room}.{part} imports '
                                f'{imported.module} ({where})')
    assert not problems, _report(problems, 'parts import one way')


def test_no_part_over_the_module_limit():
    sizes: Dict[str, int] = {}
    for module in MODULES:
        part = _part_of(module.name)
        if part is not None and not module.path.endswith('__init__.py'):
            sizes[f'{module.room}.{part}'] = sizes.get(f'{module.room}.{part}', 0) + 1
    problems = [f'{part}: {count} modules' for part, count in sorted(sizes.items())
                if count > MAX_PART_MODULES]
    assert not problems, _report(problems, f'no part over {MAX_PART_MODULES} modules')


def test_the_tests_mirror_the_parts():
    problems = []
    for room, parts in PART_IMPORTS.items():
        folder = os.path.join(REPO_ROOT, 'test', room)
        for name in sorted(os.listdir(folder)):
            if os.path.isdir(os.path.join(folder, name)) and name != '__pycache__' and (
                    name not in parts):
                problems.append(f'test/{room}/{name}: no part {room}.{name}')
    assert not problems, _report(problems, 'test folders named after the parts')


# --- (b) no import inside a function except to defer a heavy dependency --------------------

def test_no_qrm_ros_import_inside_a_function():
    problems = [f'{module.path}:{imported.line}: imports {imported.module} inside a function'
                for module in MODULES for imported in _imports(module)
                if imported.in_function and imported.module not in DEFERRED_IMPORTS]
    assert not problems, _report(problems, 'imports at the top of the module')


def test_every_deferred_import_names_a_module_that_exists():
    missing = sorted(set(DEFERRED_IMPORTS) - MODULE_NAMES)
    assert not missing, f'DEFERRED_IMPORTS names modules that do not exist: {missing}'


def _import_graph() -> Dict[str, Set[str]]:
    """Module -> the qrm_ros modules it imports (inside functions too)."""
    return {m.name: {i.module for i in _imports(m) if i.module in MODULE_NAMES} - {m.name}
            for m in MODULES}


def _circles(graph: Dict[str, Set[str]]) -> List[List[str]]:
    """The strongly connected groups of more than one module (Tarjan's algorithm)."""
    order: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    on_stack: Set[str] = set()
    circles = []

    def visit(node: str) -> None:
        order[node] = low[node] = len(order)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph[node]):
            if target not in order:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], order[target])
        if low[node] == order[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                circles.append(sorted(group))

    for node in sorted(graph):
        if node not in order:
            visit(node)
    return circles


def test_no_circle_of_imports_even_inside_functions():
    # A deferred import may put off a heavy library, never hide a circle between modules.
    circles = [' <-> '.join(group) for group in _circles(_import_graph())]
    assert not circles, _report(circles, 'no circle of imports')


# --- (c) no private name imported across modules ------------------------------------------

def _private_uses(modules: List[Module]) -> List[str]:
    """Where these modules take a private name of another qrm_ros module."""
    problems = []
    for module in modules:
        module_aliases = {}  # local name -> qrm_ros module it is bound to
        for node in _nodes(module):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split('.')[0] == PACKAGE:
                        module_aliases[alias.asname or alias.name] = alias.name
            elif isinstance(node, ast.ImportFrom):
                source = _resolve(module, node)
                if source.split('.')[0] != PACKAGE:
                    continue
                for alias in node.names:
                    if _is_private(alias.name):
                        problems.append(f'{module.path}:{node.lineno}: imports {alias.name} '
                                        f'from {source}')
                    elif f'{source}.{alias.name}' in MODULE_NAMES:
                        module_aliases[alias.asname or alias.name] = f'{source}.{alias.name}'
        for node in _nodes(module):
            if (isinstance(node, ast.Attribute) and _is_private(node.attr)
                    and isinstance(node.value, ast.Name) and node.value.id in module_aliases):
                problems.append(f'{module.path}:{node.lineno}: uses {node.value.id}.{node.attr} '
                                f'of {module_aliases[node.value.id]}')
        for imported in _imports(module):
            private = [p for p in imported.module.split('.') if _is_private(p)]
            if private and imported.module.rsplit('.', 1)[0] != module.name.rsplit('.', 1)[0]:
                problems.append(f'{module.path}:{imported.line}: imports the private module '
                                f'{imported.module}')
    return problems


def test_no_private_name_imported_from_another_module():
    assert not (problems := _private_uses(MODULES)), _report(
        problems, 'no private name across modules')


def _read_tests() -> List[Module]:
    tests = []
    for base, folders, names in os.walk(os.path.join(REPO_ROOT, 'test')):
        folders[:] = sorted(f for f in folders if f not in ('__pycache__', 'data'))
        for name in sorted(n for n in names if n.endswith('.py')):
            path = os.path.relpath(os.path.join(base, name), REPO_ROOT)
            with open(os.path.join(REPO_ROOT, path), encoding='utf-8') as handle:
                text = handle.read()
            tests.append(Module(_module_name(path), path, None, len(text.splitlines()),
                                ast.parse(text, path)))
    return tests


def test_tests_use_public_names_only():
    assert not (problems := _private_uses(_read_tests())), _report(
        problems, 'tests use public names')


# --- (d) modules and classes small enough to read ------------------------------------------

def test_no_module_over_the_line_limit():
    problems = [f'{m.path}: {m.lines} lines' for m in MODULES if m.lines > MAX_MODULE_LINES]
    assert not problems, _report(problems, f'no module over {MAX_MODULE_LINES} lines')


def test_no_class_over_the_line_limit():
    problems = []
    for module in MODULES:
        for node in _nodes(module):
            if isinstance(node, ast.ClassDef):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_CLASS_LINES:
                    problems.append(f'{module.path}:{node.lineno}: class {node.name}: '
                                    f'{length} lines')
    assert not problems, _report(problems, f'no class over {MAX_CLASS_LINES} lines')


# --- (e) commands live in cli --------------------------------------------------------------

def test_only_commands_define_main_or_parse_arguments():
    problems = []
    for module in MODULES:
        if module.room == COMMAND_ROOM:
            continue
        for node in module.tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == 'main':
                problems.append(f'{module.path}:{node.lineno}: defines main')
        for node in _nodes(module):
            if isinstance(node, ast.Import):
                taken = [a.name for a in node.names if a.name.split('.')[0] == 'argparse']
            elif isinstance(node, ast.ImportFrom) and not node.level:
                taken = ['argparse'] if (node.module or '').split('.')[0] == 'argparse' else []
            else:
                continue
            if taken:
                problems.append(f'{module.path}:{node.lineno}: imports argparse')
    assert not problems, _report(problems, f'main and argparse only in qrm_ros/{COMMAND_ROOM}/')


# --- (f) nothing points outside the repository ---------------------------------------------

def _repository_files() -> List[str]:
    try:
        listed = subprocess.run(['git', 'ls-files', '-z'], cwd=REPO_ROOT, capture_output=True,
                                check=True).stdout
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: walk the tree
        files = []
        for base, folders, names in os.walk(REPO_ROOT):
            folders[:] = [f for f in folders if f not in NOT_IN_REPOSITORY]
            files += [os.path.relpath(os.path.join(base, n), REPO_ROOT) for n in names]
        return sorted(files)
    return [os.fsdecode(p) for p in listed.split(b'\0') if p]


def _text(path: str) -> Optional[str]:
    """The file's text, or None for a binary file (or one deleted but not yet committed)."""
    try:
        with open(os.path.join(REPO_ROOT, path), 'rb') as handle:
            data = handle.read()
    except (FileNotFoundError, IsADirectoryError):
        return None
    if b'\0' in data[:8192]:
        return None
    return data.decode('utf-8', errors='replace')


def test_no_file_names_notes_outside_the_repository():
    problems: Dict[str, List[str]] = {}
    for path in _repository_files():
        text = _text(path)
        if text is None:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            found = [p for p in OUTSIDE_PATHS if p in line]
            if found:
                problems.setdefault(path, []).append(f'{path}:{number}: {", ".join(found)}')
    lines = [line for found in problems.values() for line in found]
    assert not lines, _report(lines, 'no path outside the repository')
