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
Fuzzing ``qrm_analyze`` with damaged and odd recordings (test/damaged_runs.py).

Every case goes through ``main()`` as a user would run it, and must end cleanly: an allowed
exit status, never a traceback, one line on stderr when refused, no output file left when
refused, JSON without NaN, and no silent loss: the messages the file held are all accounted
for (used, counted once as exact repeats, or listed as lost or excluded), and a complete
analysis (exit 0) used every one of them.

The default run makes QRM_FUZZ_CASES=300 cases; set it higher (e.g. 5000) for a long run, and
QRM_FUZZ_SEED to explore other files.
"""

import glob
import json
import os

import pytest

from qrm_ros.analysis import recorded_run
from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from damaged_runs import cases
from repo_paths import TEST_DATA

DATA = TEST_DATA
CASES = int(os.environ.get('QRM_FUZZ_CASES', '300'))
SEED = int(os.environ.get('QRM_FUZZ_SEED', '20261122'))


@pytest.fixture(scope='module')
def logs():
    return {os.path.basename(path)[:-5]: open(path, 'rb').read()
            for path in sorted(glob.glob(os.path.join(DATA, '*.mcap')))}


@pytest.fixture(scope='module')
def fuzz_cases(logs):
    return cases(logs, CASES, SEED)


@pytest.fixture(scope='module')
def baselines(logs, tmp_path_factory):
    """The undamaged logs' JSON documents."""
    folder = tmp_path_factory.mktemp('baselines')
    found = {}
    for name, data in logs.items():
        path = folder / f'{name}.mcap'
        path.write_bytes(data)
        assert qrm_analyze.main([str(path), '--json', str(folder / f'{name}.json')]) == 0
        found[name] = json.loads((folder / f'{name}.json').read_text())
    return found


def _strict_json(text):
    def refuse(constant):
        raise AssertionError(f'JSON holds {constant}')
    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize('number', range(CASES))
def test_damaged_run_ends_cleanly_and_loses_nothing_silently(number, fuzz_cases, baselines,
                                                             tmp_path, capsys):
    case = fuzz_cases[number]
    run = tmp_path / 'run.mcap'
    run.write_bytes(case.data)
    output = tmp_path / 'out.json'
    code = qrm_analyze.main([str(run), '--json', str(output)])
    out, err = capsys.readouterr()
    context = f'{case.name}: exit {code}\n{err}'
    assert 'Traceback' not in err + out, context
    assert code in case.allowed, context
    assert not [p for p in os.listdir(tmp_path) if p.endswith('.part')], context
    if code == exit_codes.EXIT_BAD_INPUT:
        assert len(err.strip().splitlines()) == 1 and err.startswith('qrm_analyze: error: '), \
            context
        assert not output.exists(), context
        return
    document = _strict_json(output.read_text())
    counts, losses = document['messages'], document['losses']
    # Messages used without their efforts are counted in used.
    excluded = sum(loss['messages'] for loss in losses
                   if loss['stage'] == recorded_run.IN_MESSAGE)
    assert counts['read'] == counts['used'] + counts['repeated'] + excluded, context
    unknown = any(loss['messages'] is None for loss in losses
                  if loss['stage'] == recorded_run.IN_FILE)
    if not unknown:
        lost = sum(loss['messages'] for loss in losses if loss['stage'] == recorded_run.IN_FILE)
        assert counts['read'] + lost == case.messages, context
    if code == exit_codes.EXIT_OK:
        assert document['complete'] and not losses, context
        assert counts['used'] + counts['repeated'] == case.messages, context
    else:
        assert not document['complete'] and 'warning' in err, context
    if case.gap:
        assert any(t['kind'] == 'gap' for t in document['transitions']), context
    if case.same_results:
        baseline = baselines[case.name.rsplit('-', 1)[1]]
        assert document['segments'] == baseline['segments'], context
