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
from damaged_runs import (assert_supported, cases, decode_joint_state, encode_joint_state,
                          flip_bit, incomplete_or_unsupported, put_together, take_apart)
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
    """
    The undamaged logs' JSON documents.

    Each is complete; the motor log's efforts have no sampling bound (its steady running
    is simulated, not in closed form), so it exits 3 for that alone.
    """
    folder = tmp_path_factory.mktemp('baselines')
    found = {}
    for name, data in logs.items():
        path = folder / f'{name}.mcap'
        path.write_bytes(data)
        code = qrm_analyze.main([str(path), '--json', str(folder / f'{name}.json')])
        found[name] = json.loads((folder / f'{name}.json').read_text())
        assert found[name]['complete'] and not found[name]['losses']
        if 'motor' in name:
            assert code == exit_codes.EXIT_INCOMPLETE and incomplete_or_unsupported(
                found[name])
        else:
            assert code == exit_codes.EXIT_OK
    return found


def _allowed(case):
    """A case's exit codes; from a log that exits 3 for its sampling alone, 3 for its 0."""
    if 'motor' not in case.name.rsplit('-', 1)[1]:
        return case.allowed
    return frozenset(exit_codes.EXIT_INCOMPLETE if code == exit_codes.EXIT_OK else code
                     for code in case.allowed)


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
    assert code in _allowed(case), context
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
        assert_supported(document['segments'], 'motor' not in case.name, context)
    else:
        assert incomplete_or_unsupported(document) and 'warning' in err, context
    if case.gap:
        assert any(t['kind'] == 'gap' for t in document['transitions']), context
    if case.same_results:
        baseline = baselines[case.name.rsplit('-', 1)[1]]
        assert document['segments'] == baseline['segments'], context


def test_one_flipped_joint_value_is_dropped_and_said_with_its_time_and_check(
        logs, tmp_path, capsys):
    # Re-encoded, so the chunk CRCs cover the changed value (as a writer without CRCs): only
    # the physics can see it.
    recorded = take_apart(logs['steady_positive_offset'])
    message = recorded.joint_states()[300]
    decoded = decode_joint_state(message[4])
    decoded.position[3] = flip_bit(float(decoded.position[3]), 50)  # the ram position
    message[4] = encode_joint_state(decoded)
    run = tmp_path / 'flipped.mcap'
    run.write_bytes(put_together(recorded))
    code = qrm_analyze.main([str(run), '--json', str(tmp_path / 'out.json')])
    err = capsys.readouterr().err
    assert code == exit_codes.EXIT_INCOMPLETE, err
    document = json.loads((tmp_path / 'out.json').read_text())
    loss, = document['losses']
    assert loss['messages'] == 1 and loss['stage'] == recorded_run.IN_MESSAGE
    assert loss['reason'] == ('the ram position does not follow from the input angle and the '
                              'offset (closed form, check ram_position)')
    assert loss['reason'] in err
    # Its time: log time after the first message, as every loss says it.
    first = recorded.joint_states()[0][1]
    assert loss['start_time'] == loss['end_time'] == pytest.approx((message[1] - first) * 1e-9)
    assert document['messages']['used'] == len(recorded.joint_states()) - 1


def test_a_run_of_another_geometry_is_refused_in_one_line(logs, tmp_path, capsys):
    recorded = take_apart(logs['steady_positive_offset'])
    geometry = recorded.metadata['qrm_ros.geometry']
    geometry['ram_height'] = repr(float(geometry['ram_height']) * 1.05)
    run = tmp_path / 'foreign.mcap'
    run.write_bytes(put_together(recorded))
    assert qrm_analyze.main([str(run)]) == exit_codes.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.startswith('qrm_analyze: error: ') and len(err.strip().splitlines()) == 1
    assert 'contradict the closed form of the geometry in use' in err
    assert 'recorded with another geometry? Give it with the geometry options' in err
