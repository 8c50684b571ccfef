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
Each recorded joint state checked against the closed form, sample by sample.

A joint-state sample is redundant: the flywheel's angle and the ram's position follow from
the input angle, the offset and the geometry, and their speeds from the input speed and the
offset's rate (mechanism_state.state). A value changed on its way (a flipped bit in a file
without CRCs), or a recording made with another geometry, breaks that. The tolerance is far
above round-off (the node publishes exactly what the closed form gives, to 1e-15) and far
below any change that would move a figure. numpy only.
"""

from typing import Dict

import numpy as np

from qrm_ros.core.geometry import Geometry, TWO_PI
from qrm_ros.core.mechanism_state import state

__all__ = ['CONSISTENCY_CHECKS', 'CONSISTENCY_TOLERANCE', 'inconsistent_samples']

# Relative to 1 + |the closed form's value| (rad, m, rad/s, m/s): a million times round-off.
CONSISTENCY_TOLERANCE = 1e-9
# What each check compares, in the words a report uses.
CONSISTENCY_CHECKS = {
    'offset': 'the offset is not a finite value within the coupling radius',
    'flywheel_angle': 'the flywheel angle does not follow from the input angle and the offset',
    'flywheel_speed': 'the flywheel speed does not follow from the input speed and the '
                      "offset's rate",
    'ram_position': 'the ram position does not follow from the input angle and the offset',
    'ram_velocity': 'the ram velocity does not follow from the input speed and the offset\'s '
                    'rate',
}


def _off(measured: np.ndarray, expected: np.ndarray, angle: bool = False) -> np.ndarray:
    difference = np.asarray(measured, dtype=float) - expected
    if angle:  # the recorded flywheel angle is wrapped to [-pi, pi)
        difference = (difference + np.pi) % TWO_PI - np.pi
    return ~(np.abs(difference) <= CONSISTENCY_TOLERANCE * (1.0 + np.abs(expected)))


def inconsistent_samples(geometry: Geometry, input_angle: np.ndarray, input_speed: np.ndarray,
                         offset: np.ndarray, offset_rate: np.ndarray,
                         flywheel_angle: np.ndarray, flywheel_speed: np.ndarray,
                         ram_position: np.ndarray,
                         ram_velocity: np.ndarray) -> Dict[str, np.ndarray]:
    """
    Return, per check of CONSISTENCY_CHECKS, which samples fail it (boolean arrays).

    A sample whose offset is unusable fails 'offset' only (the others cannot be worked out
    for it); a sample with a non-finite value fails the check of that value.
    """
    offset = np.asarray(offset, dtype=float)
    usable = np.isfinite(offset) & (np.abs(offset) < geometry.coupling_radius)
    failed = {name: np.zeros(offset.shape, dtype=bool) for name in CONSISTENCY_CHECKS}
    failed['offset'] = ~usable
    if not usable.any():
        return failed
    expected = state(geometry, offset[usable], np.asarray(input_angle, dtype=float)[usable],
                     np.asarray(input_speed, dtype=float)[usable], 0.0,
                     np.asarray(offset_rate, dtype=float)[usable])
    recorded = {'flywheel_angle': flywheel_angle, 'flywheel_speed': flywheel_speed,
                'ram_position': ram_position, 'ram_velocity': ram_velocity}
    for name, values in recorded.items():
        failed[name][usable] = _off(np.asarray(values, dtype=float)[usable],
                                    getattr(expected, name), angle=name == 'flywheel_angle')
    return failed
