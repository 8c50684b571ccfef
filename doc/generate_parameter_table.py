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
Print the parameter table of doc/node.md, generated from the node's own parameter table.

The node's parameters are data (``PARAMETERS`` in ``qrm_ros.node.shaper_sim.shaper_parameters``:
default, unit, meaning, rule, read-only flag); this script turns that data into the Markdown table
that doc/node.md holds between the marker comments, and test/test_docs.py fails when the two
differ.
After adding or changing a parameter, regenerate the table in place:

    python3 dev.py run python doc/generate_parameter_table.py --write

Without ``--write`` it prints the table.
"""

import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
NODE_PAGE = os.path.join(ROOT, 'doc', 'node.md')
BEGIN = '<!-- parameter table: begin -->'
END = '<!-- parameter table: end -->'
HEADER = ('| Parameter | Default | Unit | Allowed values | Live | Meaning |\n'
          '|---|---|---|---|---|---|\n')


def _cell(text):
    """Make text safe inside a Markdown table cell: one line, | and * escaped."""
    return ' '.join(str(text).split()).replace('|', '\\|').replace('*', '\\*')


def _default(value, shown):
    if isinstance(value, str):
        return f'`{value}`'
    return shown(value)


def parameter_table():
    """Return the Markdown table of shaper_sim's parameters, one row per parameter."""
    # The working tree's package, not an installed copy of it.
    if ROOT not in sys.path:
        sys.path.insert(0, ROOT)
    from qrm_ros.core.kinematics.geometry import Geometry
    from qrm_ros.node.shaper_sim import shaper_parameters as sp
    values = sp.default_values()
    geometry = Geometry(**{name: values[name] for name in sp.GEOMETRY_NAMES})
    view = sp.View(values, geometry, values['input_speed'])
    rows = []
    for name, spec in sp.PARAMETERS.items():
        cells = [f'`{name}`', _default(spec.default, sp.shown), spec.unit or '–',
                 sp.allowed_text(name, view), 'read-only' if spec.read_only else 'yes',
                 spec.description]
        rows.append('| ' + ' | '.join(_cell(cell) for cell in cells) + ' |\n')
    return HEADER + ''.join(rows)


def marked_table(text):
    """Return the part of a page between the parameter table's marker comments."""
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise ValueError(f'the page lacks the markers {BEGIN!r} ... {END!r}')
    return text[start + len(BEGIN):end].strip('\n') + '\n'


def write_table(path=NODE_PAGE):
    """Replace the table between the markers of the page by the generated one."""
    with open(path) as handle:
        text = handle.read()
    table = parameter_table()
    changed = marked_table(text) != table
    start = text.find(BEGIN) + len(BEGIN)
    with open(path, 'w') as handle:
        handle.write(text[:start] + '\n' + table + text[text.find(END):])
    return changed


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog='generate_parameter_table',
        description="Print shaper_sim's parameter table (Markdown) from the code's table.")
    parser.add_argument('--write', action='store_true',
                        help=f'replace the table in {os.path.relpath(NODE_PAGE, ROOT)}')
    args = parser.parse_args(argv)
    if args.write:
        changed = write_table()
        print(f'{os.path.relpath(NODE_PAGE, ROOT)}: '
              f'{"table updated" if changed else "table already up to date"}')
    else:
        sys.stdout.write(parameter_table())
    return 0


if __name__ == '__main__':
    sys.exit(main())
