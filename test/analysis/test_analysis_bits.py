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
Every figure qrm_analyze reports of the golden logs and the shipped examples, as recorded.

The analysis of a file is promised bit for bit on every machine of the reference kind
(doc/reproducibility.md): its JSON documents are held to test/data/analysis_results.json,
written by the code as it stands (a change that means to move a figure rewrites them, with
its reason in the commit):

    python3 dev.py run python test/analysis/test_analysis_bits.py --write

Elsewhere the measured figures stay exact (the stroke measurement calls no C library
function), while the theory and the sampling bounds, which do, may move in their last bits:
they are compared within THEORY_TOLERANCE, and a sampling bound within BOUND_TOLERANCE of
itself (its step is rounded up to a 1 % grid, so a last bit can move it one grid step).
"""

import contextlib
import glob
import io
import json
import math
import os
import sys

import pytest

from qrm_ros.cli import qrm_analyze
from qrm_ros.testing import EXAMPLES_FOLDER, reference_math

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from repo_paths import TEST_DATA  # noqa: E402  (test/ on the path, as the rooms' tests do)

pytestmark = pytest.mark.bits

RESULTS = os.path.join(TEST_DATA, 'analysis_results.json')
RUNS = {**{f'golden/{os.path.basename(path)[:-5]}': path
           for path in sorted(glob.glob(os.path.join(TEST_DATA, '*.mcap')))},
        **{f'example/{os.path.basename(path)[:-5]}': path
           for path in sorted(glob.glob(os.path.join(EXAMPLES_FOLDER, '*.mcap')))}}
# Off the reference machines: absolute on values near 1 (ratios, errors), relative beyond.
THEORY_TOLERANCE = 1e-12
BOUND_TOLERANCE = 0.1
# Where the analysis writes no figure of the file's own: its path.
NOT_COMPARED = ('file',)


def analysed(path, folder):
    """qrm_analyze's JSON document of a run, as a user gets it (exit code beside it)."""
    output = os.path.join(folder, 'analysis.json')
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = qrm_analyze.main([path, '--json', output])
    with open(output) as stream:
        document = json.load(stream)
    return {'exit_code': code, **{key: value for key, value in document.items()
                                  if key not in NOT_COMPARED}}


def _differences(recorded, computed, path='', exact=True):
    """Yield (path, recorded, computed) wherever the two documents disagree."""
    if isinstance(recorded, dict) and isinstance(computed, dict):
        for key in sorted(set(recorded) | set(computed)):
            yield from _differences(recorded.get(key), computed.get(key), f'{path}.{key}',
                                    exact)
    elif isinstance(recorded, list) and isinstance(computed, list):
        if len(recorded) != len(computed):
            yield f'len({path})', len(recorded), len(computed)
        for index, (a, b) in enumerate(zip(recorded, computed)):
            yield from _differences(a, b, f'{path}[{index}]', exact)
    elif isinstance(recorded, float) and isinstance(computed, float) and not exact:
        tolerance = (BOUND_TOLERANCE * abs(recorded) if path.endswith('_sampling_bound')
                     else THEORY_TOLERANCE * max(1.0, abs(recorded)))
        if not (recorded == computed or abs(recorded - computed) <= tolerance
                or (math.isnan(recorded) and math.isnan(computed))):
            yield path, recorded, computed
    elif recorded != computed or type(recorded) is not type(computed):
        yield path, recorded, computed


@pytest.mark.parametrize('name', sorted(RUNS))
def test_the_analysis_is_as_recorded(name, tmp_path):
    with open(RESULTS) as stream:
        recorded = json.load(stream)[name]
    computed = analysed(RUNS[name], str(tmp_path))
    exact = reference_math()
    differences = list(_differences(recorded, computed, exact=exact))
    assert not differences, (f'{name} ({"bit for bit" if exact else "within the bounds"}): '
                             f'{differences[:5]}')


def test_every_run_is_held_and_says_something():
    with open(RESULTS) as stream:
        recorded = json.load(stream)
    assert set(recorded) == set(RUNS)
    assert all(document['segments'] for document in recorded.values())


if __name__ == '__main__':
    if sys.argv[1:] != ['--write']:
        sys.exit(__doc__)
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        documents = {name: analysed(path, folder) for name, path in sorted(RUNS.items())}
    with open(RESULTS, 'w') as stream:
        json.dump(documents, stream, indent=1, sort_keys=True)
        stream.write('\n')
