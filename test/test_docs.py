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
The documentation: the site builds without a warning, every relative link resolves, the
repository names no folder outside itself, the examples run, and the node's parameter table
in doc/node.md is the one the code generates.

QRM_DOCS_HTML=DIR keeps the built site in DIR (e.g. to read it in a browser).
"""

import glob
import importlib.util
import math
import os
import re
import shutil
import subprocess
import sys

import pytest

from repo_paths import REPO_ROOT as ROOT

DOC = os.path.join(ROOT, 'doc')
PAGES = sorted(['README.md', 'CONTRIBUTING.md', os.path.join('bench', 'README.md')]
               + [os.path.relpath(p, ROOT) for p in glob.glob(os.path.join(DOC, '*.md'))])
# Pages whose ```python blocks are run: they use only the package and make no files.
RUN_EXAMPLES = ['README.md', os.path.join('doc', 'api.md'), os.path.join('doc', 'design.md')]
# Not copied into the site's scratch source: environments, build outputs, caches.
NOT_SOURCES = {'.git', '.venv', 'build', 'install', 'log', 'runs', '.pytest_cache',
               '.mypy_cache', '__pycache__'}

_FENCE = re.compile(r'^(```|~~~).*?^\1', re.S | re.M)
_CODE_SPAN = re.compile(r'`[^`\n]*`')
_LINK = re.compile(r'!?\[(?:[^\]\n]|\n(?!\n))*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
_SCHEME = re.compile(r'^[a-zA-Z][a-zA-Z0-9+.-]*:')


def _read(path):
    with open(os.path.join(ROOT, path), encoding='utf-8') as handle:
        return handle.read()


def _source_copy(folder):
    """Copy the repository's sources into folder, for Sphinx to read.

    Sphinx's autosummary writes the API pages it generates into doc/generated/: there, not
    into the work tree. (MyST resolves symbolic links, so links would not do.)
    """
    ignored = shutil.ignore_patterns(*NOT_SOURCES, '*.egg-info', 'generated', '_build')
    shutil.copytree(ROOT, folder, ignore=ignored)
    return folder


def test_site_builds_without_warnings(tmp_path):
    """A broken link or anchor, a missing page or a stale API reference fails the build."""
    source = _source_copy(str(tmp_path / 'source'))
    html = os.environ.get('QRM_DOCS_HTML') or str(tmp_path / 'html')
    result = subprocess.run(
        [sys.executable, '-m', 'sphinx', '-b', 'html', '-W', '--keep-going', '-q',
         '-c', os.path.join(source, 'doc'), '-d', str(tmp_path / 'doctrees'), source, html],
        capture_output=True, text=True, cwd=str(tmp_path),
        env=dict(os.environ, QRM_DOCS_PACKAGE_ROOT=ROOT))
    assert result.returncode == 0, result.stdout + result.stderr
    assert os.path.isfile(os.path.join(html, 'doc', 'index.html'))
    assert os.path.isfile(os.path.join(html, 'doc', 'generated', 'qrm_ros.core.html'))


def _links(text):
    """Return the targets of the Markdown links and images in text, outside code."""
    text = _CODE_SPAN.sub('', _FENCE.sub('', text))
    return _LINK.findall(text)


# A control character in a page is a backslash lost on the way (the \v of \varphi, the \f of
# \frac, the \r of \right, a tab for the \t of \text: LaTeX written through a Python string).
# The math it was part of renders wrong, and Sphinx gives no warning.
_CONTROL = re.compile('[\x00-\x08\x0b\x0c\x0e-\x1f\r]|\text')


@pytest.mark.parametrize('page', PAGES)
def test_pages_hold_no_control_characters(page):
    with open(os.path.join(ROOT, page), encoding='utf-8', newline='') as handle:
        text = handle.read()
    found = [f'line {text.count(chr(10), 0, m.start()) + 1}: {m.group()!r}'
             for m in _CONTROL.finditer(text)]
    assert not found, f'{page}: ' + ', '.join(found)


def test_link_finder():
    text = ('[a](doc/node.md) ![b](images/x.png "title") [c](https://x.org/y) `[d](e.md)`\n'
            '```\n[f](g.md)\n```\n[h](node.md#parameters) [i](#local)\n')
    assert _links(text) == ['doc/node.md', 'images/x.png', 'https://x.org/y',
                            'node.md#parameters', '#local']


@pytest.mark.parametrize('page', PAGES)
def test_relative_links_resolve(page):
    missing = []
    for target in _links(_read(page)):
        if _SCHEME.match(target) or target.startswith('#'):
            continue
        path = os.path.normpath(os.path.join(ROOT, os.path.dirname(page),
                                             target.split('#')[0]))
        if not os.path.exists(path) or not path.startswith(ROOT + os.sep):
            missing.append(target)
    assert not missing, f'{page}: links to files not in the repository: {missing}'


def _python_blocks(text):
    """Return each ```python block, preceded by blank lines to keep the page's line numbers."""
    return ['\n' * text.count('\n', 0, match.start(1)) + match.group(1)
            for match in re.finditer(r'^```python\n(.*?)^```', text, re.S | re.M)]


# An example line whose comment starts with the value it gives: `expression  # 3.2365…` or
# `a, b  # (3.2365…, 6.104)`. A trailing … means the digits shown are the value's first ones;
# without it the value rounds to the digits shown.
_DOCUMENTED_VALUE = re.compile(r'^(?P<expression>[^#]+?)\s+#\s*\(?(?P<values>[−-]?\d[\d.]*…?'
                               r'(?:,\s*[−-]?\d[\d.]*…?)*)\)?(?:\s|$)')


def _documented_values(block):
    for line in block.splitlines():
        match = _DOCUMENTED_VALUE.match(line)
        if match:
            yield match['expression'], [value.strip().replace('−', '-')
                                        for value in match['values'].split(',')]


def _shows(value, documented):
    if documented.endswith('…'):
        return repr(float(value)).startswith(documented[:-1])
    decimals = len(documented.partition('.')[2])
    return round(float(value), decimals) == float(documented)


@pytest.mark.parametrize('page', RUN_EXAMPLES)
def test_python_examples_run_and_give_the_values_they_show(page, tmp_path, monkeypatch):
    blocks = _python_blocks(_read(page))
    assert blocks, f'{page} has no Python example'
    monkeypatch.chdir(tmp_path)
    checked = 0
    for block in blocks:
        namespace = {'__name__': '__doc_example__'}
        exec(compile(block, page, 'exec'), namespace)
        for expression, documented in _documented_values(block):
            values = eval(expression, namespace)
            values = values if isinstance(values, tuple) else (values,)
            assert len(values) == len(documented), (page, expression)
            for value, shown in zip(values, documented):
                assert _shows(value, shown), f'{page}: {expression} gives {value!r}, not {shown}'
                checked += 1
    assert checked, f'{page} shows no value its examples give'


def _generator():
    path = os.path.join(DOC, 'generate_parameter_table.py')
    spec = importlib.util.spec_from_file_location('generate_parameter_table', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_parameter_table_matches_the_code():
    generator = _generator()
    documented = generator.marked_table(_read(os.path.join('doc', 'node.md')))
    assert documented == generator.parameter_table(), (
        'doc/node.md\'s parameter table differs from the node\'s PARAMETERS: run '
        '"python3 dev.py run python doc/generate_parameter_table.py --write"')


def test_parameter_table_has_every_parameter():
    from qrm_ros.node.shaper_sim.shaper_parameters import PARAMETERS
    table = _generator().parameter_table()
    assert [row.split('`')[1] for row in table.splitlines()[2:]] == list(PARAMETERS)


def _main_job_rows(text):
    """Each row of the main job's table in the text: (offset, offset/h, speed, pairs), columns."""
    for line in text.splitlines():
        parts = line.split('|')
        head = parts[0].split()
        if len(parts) == 4 and len(head) == 4 and re.fullmatch(r'[-+]?\d+\.\d+', head[0]):
            yield ([float(value) for value in head],
                   [[float(value) for value in part.replace('±', ' ').split()]
                    for part in parts[1:]])


def test_the_readme_main_job_table_shows_the_closed_form():
    """
    The README's example run: its theory columns are the core's, its errors the rows' own.

    The default schedule, then the short stroke (offset 0, then the long stroke's time ratio
    held); each figure's sampling bound covers its error.
    """
    import dataclasses
    from qrm_ros.cli.qrm_main import DEFAULT_OFFSETS_MM, SHORT_STROKE_MM
    from qrm_ros.core import Geometry, peak_speed_ratio, speed_ratio, time_ratio
    from qrm_ros.core.kinematics.offset_inverses import offset_for_time_ratio
    geometry = Geometry.paper()
    stroke = SHORT_STROKE_MM * 1e-3  # its crank radius written out (doc/mechanism.md)
    short = dataclasses.replace(geometry, crank_radius=stroke * geometry.pivot_distance
                                / math.sqrt(4.0 * geometry.ram_height ** 2 + stroke ** 2))
    held = float(offset_for_time_ratio(short, time_ratio(geometry, 0.0)))
    expected = ([(geometry, mm * 1e-3) for mm in DEFAULT_OFFSETS_MM]
                + [(short, 0.0), (short, held)])
    rows = list(_main_job_rows(_read('README.md')))
    assert [row[0][0] for row in rows] == [round(offset * 1e3, 2) for _, offset in expected], (
        'the README shows the default schedule, then the short stroke')
    for ((_shown_mm, ratio_h, input_speed, _pairs), columns), (setting, offset) in zip(
            rows, expected):
        assert ratio_h == pytest.approx(offset / setting.pivot_distance, abs=5e-6)
        assert input_speed == pytest.approx(2 * math.pi, abs=5e-5)
        theories = (time_ratio(setting, offset), speed_ratio(setting, offset),
                    peak_speed_ratio(setting, offset))
        for (measured, _spread, shown, error, sampling), theory in zip(columns, theories):
            assert shown == pytest.approx(theory, abs=5e-6)
            assert error == pytest.approx(measured / theory - 1.0, abs=6e-6 + 0.05 * abs(error))
            assert abs(error) <= sampling
