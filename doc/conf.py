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
Sphinx configuration of the qrm_ros documentation site (MyST Markdown, autodoc, autosummary).

The site's source is the repository itself, so that the README, CONTRIBUTING.md,
bench/README.md and test/data/README.md are pages of it and every relative link between them
and doc/ resolves:

    python3 dev.py run python -m sphinx -W --keep-going -c doc . /tmp/qrm_site

test/test_docs.py builds it that way, warnings as errors, from a scratch copy, so that the API
pages autosummary generates (doc/generated/) land outside the work tree; a build in the work
tree leaves them there. Built from doc/ alone, as rosdoc2
does, the pages of doc/ build and the links out of doc/ warn. No network is used: intersphinx
is off, and MathJax is only referenced by the HTML pages.
"""

import os
import re
import sys

DOC = os.path.dirname(os.path.realpath(__file__))
# The package documented: the work tree's, not an installed copy. QRM_DOCS_PACKAGE_ROOT names
# another checkout (the test builds a scratch copy of the pages, but imports the work tree,
# whose numba kernels are compiled and cached already).
ROOT = os.environ.get('QRM_DOCS_PACKAGE_ROOT') or os.path.dirname(DOC)
if os.path.isfile(os.path.join(ROOT, 'package.xml')):
    sys.path.insert(0, ROOT)

project = 'qrm_ros'
author = 'qrm_ros developers'
copyright = '2026, qrm_ros developers'
release = '0.1.0'

extensions = [
    'myst_parser',
    'sphinx.ext.autodoc',
    'sphinx.ext.autosummary',
    'sphinx.ext.mathjax',
]
source_suffix = {'.md': 'markdown', '.rst': 'restructuredtext'}
# Absolute: autosummary looks templates up from the source folder, which is the repository
# root here (a relative path would silently fall back to Sphinx's own template).
templates_path = [os.path.join(DOC, '_templates')]
# The repository root is the source folder: read only the documentation in it.
root_doc = 'doc/index'
include_patterns = ['README.md', 'CONTRIBUTING.md', 'bench/README.md', 'test/data/README.md',
                    'doc/**']
exclude_patterns = ['doc/_build', 'doc/_templates', '.venv', 'build', 'install', 'log', 'runs']

myst_enable_extensions = ['dollarmath', 'amsmath']
myst_heading_anchors = 3  # GitHub's anchors: node.md#parameters works here as there

autosummary_generate = True
autosummary_ignore_module_all = False  # a module's __all__ says what it offers
autodoc_default_options = {'members': True, 'show-inheritance': True}
autodoc_member_order = 'bysource'
# Annotations written as strings of a name imported only for type checkers: the front door's.
autodoc_type_aliases = {'MassProperties': 'qrm_ros.core.MassProperties'}
default_role = 'code'  # the docstrings write `name` for code

html_theme = 'alabaster'
html_title = 'qrm_ros'
html_static_path = []


def _adapt_to_source_folder(app, config):
    """Built from doc/ alone (rosdoc2), doc/index.md is the root and doc/** the pages."""
    source = os.path.realpath(app.srcdir)
    if source == DOC or not os.path.isdir(os.path.join(source, 'doc')):
        config.root_doc = 'index'
        config.include_patterns = ['**']
        config.exclude_patterns = ['_build', '_templates']


_LITERAL_SPAN = re.compile(r'(``.*?``|`[^`]*`)')


def _plain_text_docstring(app, what, name, obj, options, lines):
    """
    Read the docstrings as the plain text they are written in.

    They write |x| for an absolute value, which reStructuredText would take for a
    substitution, and indent code and formulas after a blank line without a '::': the bars
    are escaped (outside literal text) and such blocks become literal blocks.
    """
    result = []
    literal_indent = None  # the indentation of the paragraph that opened a literal block
    previous = ''
    for line in lines:
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None:
            if line.strip() and indent <= literal_indent:
                literal_indent = None
            else:
                result.append(line)
                previous = line
                continue
        if line.strip() and indent > 0 and not previous.strip():
            opener = next((text for text in reversed(result) if text.strip()), '')
            opener_indent = len(opener) - len(opener.lstrip())
            if indent > opener_indent and opener.strip() and not opener.endswith('::'):
                result += [' ' * opener_indent + '::', '']
                literal_indent = opener_indent
                result.append(line)
                previous = line
                continue
        if line.rstrip().endswith('::'):
            literal_indent = indent
            result.append(line)
        else:
            result.append(''.join(part if part.startswith('`') else part.replace('|', '\\|')
                                  for part in _LITERAL_SPAN.split(line)))
        previous = line
    lines[:] = result


def setup(app):
    app.connect('config-inited', _adapt_to_source_folder)
    app.connect('autodoc-process-docstring', _plain_text_docstring)
