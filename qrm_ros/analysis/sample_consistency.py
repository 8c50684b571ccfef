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
The recorded joint states judged by the physics (core.joint_consistency), for the analysis.

A sample that the closed form contradicts is dropped and said, with its time and the check
that caught it; a recording most of whose samples it contradicts was made with another
geometry (or is not this machine's), and is refused rather than analysed with the wrong one.
"""

from typing import Any, List, NamedTuple

import numpy as np

from qrm_ros.core.geometry import Geometry
from qrm_ros.core.joint_consistency import CONSISTENCY_CHECKS, inconsistent_samples

__all__ = ['ConsistencyVerdict', 'FOREIGN_FRACTION', 'judge_samples', 'SHOWN_TIMES']

# More than this fraction of the samples contradicted: not this geometry's recording.
FOREIGN_FRACTION = 0.5
# Times listed per check in a report line (the count says how many in all).
SHOWN_TIMES = 5


class ConsistencyVerdict(NamedTuple):
    """Which samples to keep, and one line per check that caught some."""

    keep: np.ndarray  # bool per sample
    lines: List[str]  # '<n> samples: <what the check says> (at t = ... s)'
    counts: List[int]  # samples each line's check caught
    foreign: bool  # most samples contradicted: another geometry


def judge_samples(geometry: Geometry, samples: Any) -> ConsistencyVerdict:
    """Judge samples (Samples of recorded_run: time, input_angle, ... arrays) sample by sample."""
    failed = inconsistent_samples(geometry, samples.input_angle, samples.input_speed,
                                  samples.offset, samples.offset_rate, samples.flywheel_angle,
                                  samples.flywheel_speed, samples.ram_position,
                                  samples.ram_velocity)
    bad = np.zeros(np.shape(samples.time), dtype=bool)
    lines, counts = [], []
    for name, failing in failed.items():
        caught = failing & ~bad  # each sample said once, under the first check it fails
        count = int(np.count_nonzero(caught))
        if not count:
            continue
        bad |= caught
        times = ', '.join(f'{time:.6g}' for time in samples.time[caught][:SHOWN_TIMES])
        more = f' and {count - SHOWN_TIMES} more' if count > SHOWN_TIMES else ''
        lines.append(f'{CONSISTENCY_CHECKS[name]} (closed form, check {name}) at t = '
                     f'{times}{more} s')
        counts.append(count)
    foreign = bad.size > 0 and np.count_nonzero(bad) > FOREIGN_FRACTION * bad.size
    return ConsistencyVerdict(~bad, lines, counts, bool(foreign))
