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
The stroke measurement, bit for bit as it was: every figure, report and status value.

A change made for speed alone must not move a single bit. The cases are the golden logs
(test/data) and what plain arithmetic makes of them (decimated, run backwards, with a gap,
with a stall, made-up efforts), plus integer-valued random walks (exact zeros of both signs,
ties, crossings on samples); their results are held to fingerprints (sha256 of the values'
bytes) in test/data/stroke_measurement_bits.json, written by the code before such a change:

    python3 dev.py run python test/core/measurement/test_stroke_measurement_bits.py --write

The inputs are read from files or made by exact arithmetic, never by a transcendental
function, so the fingerprints do not depend on the CPU's vector units. The theory figures
(trigonometry) are left out of the fingerprints: this measures the measurement.
"""

import functools
import hashlib
import json
import math
import os
import sys

from diagnostic_msgs.msg import KeyValue
import numpy as np
import pytest
from qrm_ros.analysis.recorded_run import read_recording
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.measurement.stroke_monitor import StrokeMonitor
from qrm_ros.core.measurement.strokes import (find_reversals, find_stroke_pairs,
                                              measure_pair_efforts, workpiece_edge_times)
from qrm_ros.node.shaper_sim.shaper_diagnostics import stroke_pair_status

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from repo_paths import TEST_DATA  # noqa: E402  (test/ on the path, as the rooms' tests do)

pytestmark = pytest.mark.bits

FINGERPRINTS = os.path.join(TEST_DATA, 'stroke_measurement_bits.json')
LOGS = ('steady_positive_offset', 'steady_negative_offset', 'offset_and_speed_change',
        'motor_cutting_load')
NS = 1_000_000_000
# The holds a status is made with: (cutting speed target, its definition, time ratio target).
HOLDS = ((0.0, 'mean', 0.0), (0.2, 'peak', 1.5), (0.3, 'mean', 0.0))


def _fingerprint(values) -> str:
    """sha256 (16 hex digits) of an array's dtype, shape and bytes, or of strings."""
    digest = hashlib.sha256()
    if isinstance(values, (list, tuple)) and values and isinstance(values[0], str):
        digest.update('\x00'.join(values).encode())
    else:
        array = np.ascontiguousarray(values)
        digest.update(f'{array.dtype.str}{array.shape}'.encode())
        digest.update(array.tobytes())
    return digest.hexdigest()[:16]


def _made_up_efforts(speed, velocity):
    """Torque and force by exact arithmetic on recorded columns (speed logs have none)."""
    return 37.0 * velocity + 0.5 * speed, 3.0 * velocity * velocity - 11.0


def _log_case(name):
    samples = read_recording(os.path.join(TEST_DATA, f'{name}.mcap')).samples
    torque, force = samples.input_torque, samples.offset_force
    if torque is None:
        torque, force = _made_up_efforts(samples.input_speed, samples.ram_velocity)
    return {'time': samples.time, 'x': samples.ram_position, 'v': samples.ram_velocity,
            'offset': samples.offset, 'offset_rate': samples.offset_rate,
            'speed': samples.input_speed, 'torque': torque, 'force': force}


def _select(case, index):
    return {name: values[index] for name, values in case.items()}


def _backwards(case):
    """The run played backwards: time reversed, velocities and rates negated."""
    flipped = _select(case, slice(None, None, -1))
    flipped['time'] = flipped['time'][0] - flipped['time']
    for name in ('v', 'offset_rate', 'speed'):
        flipped[name] = -flipped[name]
    return flipped


def _stalled(case, at, length):
    """The ram held for `length` samples at sample `at` (the same sample repeated)."""
    index = np.concatenate([np.arange(at), np.full(length, at), np.arange(at, case['time'].size)])
    held = _select(case, index)
    held['time'] = case['time'][0] + 0.01 * np.arange(index.size)
    held['v'][at:at + length] = 0.0
    return held


def _random_walk(seed, size):
    """Integer steps (exact in binary): zeros, ties and crossings on samples."""
    generator = np.random.default_rng(seed)
    x = np.cumsum(generator.integers(-3, 4, size)).astype(float) / 8.0
    v = generator.integers(-4, 5, size).astype(float) / 4.0
    time = np.cumsum(generator.integers(1, 4, size)).astype(float) / 64.0
    speed = generator.integers(1, 9, size).astype(float)
    return {'time': time, 'x': x, 'v': v, 'offset': np.zeros(size), 'offset_rate': np.zeros(size),
            'speed': speed, 'torque': speed * v, 'force': x - v}


def _signed_zeros(seed, size):
    """A random walk whose zeros come with both signs, efforts of zeros only (peaks of 0)."""
    walk = _random_walk(seed, size)
    generator = np.random.default_rng(seed + 100)
    sign = generator.integers(0, 2, (3, size)).astype(bool)
    walk['v'] = np.where((walk['v'] == 0.0) & sign[0], -0.0, walk['v'])
    walk['torque'] = np.where(sign[1], -0.0, 0.0)
    walk['force'] = np.where(sign[2], -0.0, 0.0)
    return walk


def _long_pairs(size):
    """Pairs of thousands of samples: a triangle wave, cutting 2400 samples, returning 1600."""
    phase = np.arange(size) % 4000
    cutting = phase < 2400
    x = np.where(cutting, 1200 - phase, phase - 3600) / 1024.0
    v = np.where(cutting, -1.0, 1.5) + (phase % 7 - 3) / 64.0
    time = np.arange(size) / 4096.0
    speed = 6.0 + (phase % 5) / 8.0
    return {'time': time, 'x': x, 'v': v, 'offset': np.full(size, 0.01),
            'offset_rate': np.zeros(size), 'speed': speed, 'torque': v * speed, 'force': x * 3.0}


@functools.lru_cache(maxsize=None)
def cases():
    """Every case by name: columns of samples (s, m, m/s, rad/s, N m, N)."""
    found = {}
    for name in LOGS:
        case = _log_case(name)
        found[name] = case
        for every in (2, 3, 7, 19):
            found[f'{name}/every_{every}'] = _select(case, slice(None, None, every))
        found[f'{name}/backwards'] = _backwards(case)
        size = case['time'].size
        found[f'{name}/gap'] = _select(case, np.r_[0:size // 3, size // 3 + 40:size])
        found[f'{name}/stall'] = _stalled(case, size // 2, 30)
    for seed in range(6):
        found[f'random_walk/{seed}'] = _random_walk(seed, 400)
        found[f'signed_zeros/{seed}'] = _signed_zeros(seed, 400)
    found['long_pairs'] = _long_pairs(20000)
    return found


def _measurement(case):
    """The core's figures on the whole case, as the analysis takes them."""
    t, x, v = case['time'], case['x'], case['v']
    figures = {}
    for name, values in zip(('when', 'cut_begins', 'interval'), find_reversals(t, x, v)):
        figures[f'reversals.{name}'] = values
    pairs = find_stroke_pairs(t, x, v)
    figures.update((f'pairs.{name}', values) for name, values in pairs._asdict().items())
    efforts = measure_pair_efforts(t, case['speed'], case['torque'], case['force'], pairs)
    figures.update((f'efforts.{name}', values) for name, values in efforts._asdict().items())
    for length in (0.15, 0.3):
        edges = workpiece_edge_times(t, x, v, pairs.cutting_start, pairs.cutting_end, length)
        figures[f'edges.{length}'] = edges
        efforts = measure_pair_efforts(t, case['speed'], case['torque'], case['force'], pairs,
                                       edges)
        figures.update((f'edges.{length}.{name}', values)
                       for name, values in efforts._asdict().items())
    return figures


def _reports(case):
    """The monitor's reports and their statuses, fed sample by sample as the node does."""
    monitor = StrokeMonitor(Geometry.paper())
    stamps = np.round(case['time'] * NS).astype(np.int64) + 5 * NS
    values, words = [], []
    for index in range(stamps.size):
        completed = monitor.collect(
            int(stamps[index]), *(float(case[name][index]) for name in (
                'x', 'v', 'offset', 'offset_rate', 'speed', 'torque', 'force')))
        for report in [] if completed is None else monitor.measure(completed):
            measured = {name: value for name, value in report.values().items()
                        if not name.endswith('_theory')}
            values += list(measured.values())
            words += list(measured) + [str(report.stamp_ns), str(report.steady),
                                       str(report.sampled_without_gap)]
            for target, definition, held_ratio in HOLDS:
                status = stroke_pair_status(report, [KeyValue(key='a', value='b')], 'state',
                                            target, definition, held_ratio).status[0]
                words += [status.message] + [f'{pair.key}={pair.value}' for pair in status.values
                                             if not pair.key.endswith('_theory')]
    return {'reports.values': np.array(values), 'reports.words': words or ['none']}


def fingerprints():
    """Every case's figures as fingerprints: {case: {figure: fingerprint}}."""
    found = {}
    with np.errstate(all='ignore'):
        for name, case in cases().items():
            figures = {**_measurement(case), **_reports(case)}
            found[name] = {figure: _fingerprint(values) for figure, values in figures.items()}
    return found


@pytest.fixture(scope='module')
def computed():
    return fingerprints()


def test_the_cases_have_pairs(computed):
    with open(FINGERPRINTS) as stream:
        recorded = json.load(stream)
    assert set(computed) == set(recorded)
    counts = {name: find_stroke_pairs(case['time'], case['x'], case['v']).time_ratio.size
              for name, case in cases().items()}
    assert sum(count > 0 for count in counts.values()) >= 0.8 * len(counts), counts
    assert not math.isnan(sum(counts.values()))


@pytest.mark.parametrize('name', sorted(cases()))
def test_figures_are_bit_for_bit_as_recorded(computed, name):
    with open(FINGERPRINTS) as stream:
        recorded = json.load(stream)[name]
    changed = sorted(figure for figure in set(recorded) | set(computed[name])
                     if recorded.get(figure) != computed[name].get(figure))
    assert not changed, f'{name}: {changed}'


if __name__ == '__main__':
    if sys.argv[1:] != ['--write']:
        sys.exit(__doc__)
    with open(FINGERPRINTS, 'w') as stream:
        json.dump(fingerprints(), stream, indent=1, sort_keys=True)
        stream.write('\n')
