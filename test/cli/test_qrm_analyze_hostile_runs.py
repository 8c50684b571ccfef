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
``qrm_analyze`` on hostile recordings, one per damage class the fuzz suite draws at random:
values just inside every singular limit, and a single value flipped in each joint (the crank
radius joint and the lever included) or in a stamp of a file without CRCs.

Each ends cleanly (no traceback), in bounded time and memory (the singular runs in a
process of their own, whose peak memory is read back), and with the right exit status: 3
where data was dropped or a figure is not supported, 0 only with supported figures.
"""

import json
import math
import os
import resource
import subprocess
import sys

import pytest

from qrm_ros.cli import exit_codes
from qrm_ros.cli import qrm_analyze
from qrm_ros.core import kinematics as kin
from damaged_runs import (assert_supported, decode_joint_state, encode_joint_state, flip_bit,
                          put_together, take_apart, with_crank_radius_joint)
from repo_paths import TEST_DATA
from synthetic_run import write_run

PAPER = kin.Geometry.paper()
R1, H = PAPER.coupling_radius, PAPER.pivot_distance
GOLDEN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')
# An ordinary file takes under 100 MB; the singular ones took gigabytes before their bounds.
MEMORY_LIMIT_KB = 1_000_000
# A hang is a failure, not a slow run: far above any ordinary file's time.
HANG_SECONDS = 300


def _geometry(crank_radius):
    return kin.Geometry(R1, crank_radius, H, PAPER.ram_height)


# (name, geometry, offset m, input speed rad/s): each just inside a singular limit.
SINGULAR = [
    ('offset just below r1', PAPER, R1 * (1 - 1e-9), 2 * math.pi),
    ('offset just above -r1', PAPER, -R1 * (1 - 1e-9), 2 * math.pi),
    ('offset just below the safe offset', PAPER, PAPER.max_safe_offset * (1 - 1e-12),
     2 * math.pi),
    ('crank radius just below the pivot distance', _geometry(H * (1 - 1e-9)), 0.01,
     2 * math.pi),
    ('crank radius at 0.99 of the pivot distance', _geometry(0.99 * H), 0.01, 2 * math.pi),
    ('a crank radius near zero', _geometry(1e-9), 0.01, 2 * math.pi),
    ('an input speed near zero', PAPER, 0.01, 1e-9),
    ('an input speed far above the sampling', PAPER, 0.01, 1000.0),
]


@pytest.mark.parametrize('name, geometry, offset, speed', SINGULAR,
                         ids=[case[0] for case in SINGULAR])
def test_values_just_inside_a_singular_limit_end_cleanly_and_bounded(
        name, geometry, offset, speed, tmp_path):
    run = tmp_path / 'run.mcap'
    write_run(run, geometry, [offset], hold=3.0, input_speed=speed)
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    done = subprocess.run([sys.executable, '-m', 'qrm_ros.cli.qrm_analyze', str(run),
                           '--json', str(tmp_path / 'out.json')], capture_output=True,
                          text=True, timeout=HANG_SECONDS)
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    assert 'Traceback' not in done.stderr + done.stdout, done.stderr
    assert max(peak, before) < MEMORY_LIMIT_KB, (name, peak)
    if done.returncode == exit_codes.EXIT_BAD_INPUT:  # refused: one line, naming the value
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
        return
    document = json.loads((tmp_path / 'out.json').read_text())
    if done.returncode == exit_codes.EXIT_OK:
        assert_supported(document['segments'], True, f'{name}\n{done.stderr}')
    else:
        assert done.returncode == exit_codes.EXIT_INCOMPLETE, done.stderr
        assert 'warning' in done.stderr
    if abs(offset) > 0.9 * R1 or geometry.crank_radius > 0.98 * H or speed > 100.0:
        # Strokes too sharp for 100 Hz: unsupported figures, or strokes missed: said.
        assert done.returncode == exit_codes.EXIT_INCOMPLETE, done.stderr
    if speed < 1e-6:  # not one revolution: no figure, nothing missed
        assert done.returncode == exit_codes.EXIT_OK, done.stderr


def _flipped(joint_array, joint, tmp_path, index=300):
    """The golden log with six joints and one bit of one joint value of one message flipped."""
    recorded = take_apart(open(GOLDEN, 'rb').read())
    with_crank_radius_joint(recorded)
    message = recorded.joint_states()[index]
    decoded = decode_joint_state(message[4])
    values = getattr(decoded, joint_array)
    # A high mantissa bit of a value, or an exponent bit of a zero (0 -> 2): never round-off.
    values[joint] = flip_bit(float(values[joint]), 50 if values[joint] else 62)
    message[4] = encode_joint_state(decoded)
    run = tmp_path / 'flipped.mcap'
    run.write_bytes(put_together(recorded))
    return run, message, recorded


FLIPS = [('position', joint) for joint in range(6)] + [('velocity', joint)
                                                       for joint in range(6)]


@pytest.mark.parametrize('joint_array, joint', FLIPS)
def test_one_flipped_value_in_any_joint_is_dropped_and_named(joint_array, joint,
                                                             tmp_path, capsys):
    run, message, recorded = _flipped(joint_array, joint, tmp_path)
    code = qrm_analyze.main([str(run), '--json', str(tmp_path / 'out.json')])
    err = capsys.readouterr().err
    assert 'Traceback' not in err
    assert code == exit_codes.EXIT_INCOMPLETE, err
    document = json.loads((tmp_path / 'out.json').read_text())
    (loss,) = document['losses']
    assert loss['messages'] == 1 and '(closed form, check ' in loss['reason'], loss
    first = recorded.joint_states()[0][1]
    assert loss['start_time'] == pytest.approx((message[1] - first) * 1e-9)
    assert document['messages']['used'] == len(recorded.joint_states()) - 1


def test_the_six_joint_golden_log_is_complete_and_supported(tmp_path, capsys):
    recorded = take_apart(open(GOLDEN, 'rb').read())
    with_crank_radius_joint(recorded)
    run = tmp_path / 'six.mcap'
    run.write_bytes(put_together(recorded))
    code = qrm_analyze.main([str(run), '--json', str(tmp_path / 'out.json')])
    err = capsys.readouterr().err
    assert code == exit_codes.EXIT_OK, err
    assert_supported(json.loads((tmp_path / 'out.json').read_text())['segments'], True, err)


STAMP_FLIPS = [('sec', 0), ('sec', 3), ('sec', 30), ('sec', 31), ('nanosec', 10),
               ('nanosec', 20), ('nanosec', 29), ('nanosec', 31), ('log_time', 20),
               ('log_time', 40), ('log_time', 63)]


@pytest.mark.parametrize('field, bit', STAMP_FLIPS)
def test_one_flipped_stamp_bit_ends_cleanly_with_supported_figures(field, bit, tmp_path,
                                                                   capsys):
    recorded = take_apart(open(GOLDEN, 'rb').read())
    message = recorded.joint_states()[300]
    if field == 'log_time':
        message[1] ^= 1 << bit
    else:
        decoded = decode_joint_state(message[4])
        stamp = decoded.header.stamp
        if field == 'sec':  # an int32
            flipped = (stamp.sec & 0xFFFFFFFF) ^ (1 << bit)
            stamp.sec = flipped - (1 << 32) if flipped >= 1 << 31 else flipped
        else:
            stamp.nanosec ^= 1 << bit
        message[4] = encode_joint_state(decoded)
    run = tmp_path / 'stamp.mcap'
    run.write_bytes(put_together(recorded))
    code = qrm_analyze.main([str(run), '--json', str(tmp_path / 'out.json')])
    err = capsys.readouterr().err
    assert 'Traceback' not in err
    assert code in (exit_codes.EXIT_OK, exit_codes.EXIT_INCOMPLETE), err
    document = json.loads((tmp_path / 'out.json').read_text())
    if code == exit_codes.EXIT_OK:
        assert_supported(document['segments'], True, f'{field} bit {bit}\n{err}')


@pytest.mark.parametrize('every', [10, 40])
def test_the_golden_log_decimated_to_10_and_2_5_hz_is_said_unsupported(every, tmp_path,
                                                                       capsys):
    """The issue's case: 60 rpm kept at 10 and 2.5 samples per revolution exited 0 silently."""
    recorded = take_apart(open(GOLDEN, 'rb').read())
    kept = {id(m) for m in recorded.joint_states()[::every]}
    recorded.messages[:] = [m for m in recorded.messages
                            if m[0] != recorded.joint_channel or id(m) in kept]
    run = tmp_path / 'coarse.mcap'
    run.write_bytes(put_together(recorded))
    code = qrm_analyze.main([str(run), '--json', str(tmp_path / 'out.json')])
    out, err = capsys.readouterr()
    assert code == exit_codes.EXIT_INCOMPLETE, err
    assert 'the time ratio TR is not supported to 0.001 by the sampling' in err
    for segment in json.loads((tmp_path / 'out.json').read_text())['segments']:
        for name in ('time_ratio', 'peak_speed_ratio'):
            measured, theory = segment[f'{name}_measured'], segment[f'{name}_theory']
            bound = segment[f'{name}_sampling_bound']
            if measured is not None and bound is not None:  # a stated bound is true
                assert abs(measured - theory) <= bound + 1e-9 * abs(theory)
