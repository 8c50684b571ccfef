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

A joint-state sample is redundant: the flywheel's angle, the lever's and the ram's position
follow from the input angle, the offset, the crank radius in force and the geometry, and
their speeds from the input speed, the offset's rate and the stroke screw's rate
(mechanism_state.state). A value changed on its way (a flipped bit in a file without CRCs),
or a recording made with another geometry, breaks that. The tolerance is far above
round-off (the node publishes exactly what the closed form gives, to 1e-15) and far below
any change that would move a figure. numpy only.
"""

import dataclasses
from typing import Dict, Optional, Tuple

import numpy as np

from qrm_ros.core.kinematics.geometry import Geometry, TWO_PI
from qrm_ros.core.kinematics.mechanism_state import state

__all__ = ['CONSISTENCY_CHECKS', 'CONSISTENCY_TOLERANCE', 'inconsistent_samples',
           'misplaced_stamps']

# Relative to 1 + |the closed form's value| (rad, m, rad/s, m/s): a million times round-off.
CONSISTENCY_TOLERANCE = 1e-9
# What each check compares, in the words a report uses.
CONSISTENCY_CHECKS = {
    'offset': 'the offset is not a finite value within the coupling radius',
    'crank_radius': 'the crank radius is not a finite value between 0 and the pivot '
                    'distance, or its rate is not finite',
    'flywheel_angle': 'the flywheel angle does not follow from the input angle and the offset',
    'flywheel_speed': 'the flywheel speed does not follow from the input speed and the '
                      "offset's rate",
    'lever_angle': 'the lever angle does not follow from the input angle, the offset and the '
                   'crank radius',
    'lever_speed': "the lever speed does not follow from the input speed, the offset's rate "
                   "and the crank radius's rate",
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
                         ram_position: np.ndarray, ram_velocity: np.ndarray,
                         lever_angle: Optional[np.ndarray] = None,
                         lever_speed: Optional[np.ndarray] = None,
                         crank_radius: Optional[np.ndarray] = None,
                         crank_radius_rate: Optional[np.ndarray] = None
                         ) -> Dict[str, np.ndarray]:
    """
    Return, per check of CONSISTENCY_CHECKS, which samples fail it (boolean arrays).

    A sample whose offset or crank radius is unusable fails that check only (the others
    cannot be worked out for it); a sample with a non-finite value fails the check of that
    value. crank_radius (m) and its rate (m/s): the crank radius joint's, NaN (or None) for
    a sample without it, whose crank radius is the geometry's. The lever is judged when
    given (recordings without it leave it out).
    """
    offset = np.asarray(offset, dtype=float)
    failed = {name: np.zeros(offset.shape, dtype=bool) for name in CONSISTENCY_CHECKS}
    radius, radius_rate = _radius_in_force(geometry, offset.shape, crank_radius,
                                           crank_radius_rate)
    failed['offset'] = ~(np.isfinite(offset) & (np.abs(offset) < geometry.coupling_radius))
    failed['crank_radius'] = ~failed['offset'] & ~(
        np.isfinite(radius) & (radius > 0.0) & (radius < geometry.pivot_distance)
        & np.isfinite(radius_rate))
    usable = ~failed['offset'] & ~failed['crank_radius']
    if not usable.any():
        return failed
    # Geometry's fields broadcast as arrays (design sweeps): one crank radius per sample.
    in_force = dataclasses.replace(geometry, crank_radius=radius[usable])  # type: ignore[arg-type]
    recorded = {'flywheel_angle': flywheel_angle, 'flywheel_speed': flywheel_speed,
                'lever_angle': lever_angle, 'lever_speed': lever_speed,
                'ram_position': ram_position, 'ram_velocity': ram_velocity}
    with np.errstate(all='ignore'):  # absurd finite values overflow: they fail, as they must
        expected = state(in_force, offset[usable], np.asarray(input_angle, dtype=float)[usable],
                         np.asarray(input_speed, dtype=float)[usable], 0.0,
                         np.asarray(offset_rate, dtype=float)[usable], radius_rate[usable])
        for name, values in recorded.items():
            if values is not None:
                failed[name][usable] = _off(np.asarray(values, dtype=float)[usable],
                                            getattr(expected, name),
                                            angle=name == 'flywheel_angle')
    return failed


def _radius_in_force(geometry: Geometry, shape: Tuple[int, ...],
                     crank_radius: Optional[np.ndarray],
                     crank_radius_rate: Optional[np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
    """Return each sample's crank radius and its rate: the recorded ones, else the geometry's."""
    recorded = (np.full(shape, np.nan) if crank_radius is None
                else np.asarray(crank_radius, dtype=float))
    rate = (np.full(shape, np.nan) if crank_radius_rate is None
            else np.asarray(crank_radius_rate, dtype=float))
    absent = np.isnan(recorded)
    return (np.where(absent, float(geometry.crank_radius), recorded),
            np.where(absent, 0.0, rate))


def misplaced_stamps(time: np.ndarray, input_angle: np.ndarray,
                     input_speed: np.ndarray) -> np.ndarray:
    """
    Return which samples' stamps alone contradict the input shaft's advance (booleans).

    At a constant input speed the input angle advances by the speed times the step, exactly
    as the node publishes it (to 1e-14 rad). A stamp changed on its way (a flipped bit)
    breaks that on both sides of its sample, in opposite directions; a pause or a clock
    jump breaks it on one side only and is not blamed on a sample. Steps across a speed
    change are not judged (the motor drive's speed changes at every sample).
    """
    t = np.asarray(time, dtype=float)
    angle = np.asarray(input_angle, dtype=float)
    speed = np.asarray(input_speed, dtype=float)
    misplaced = np.zeros(t.shape, dtype=bool)
    if t.size < 3:
        return misplaced
    with np.errstate(all='ignore'):
        expected = np.diff(t) * speed[1:]
        residual = (np.diff(angle) - expected + np.pi) % TWO_PI - np.pi
        broken = (speed[1:] == speed[:-1]) & ~(
            np.abs(residual) <= CONSISTENCY_TOLERANCE * (1.0 + np.abs(expected)))
    misplaced[1:-1] = (broken[:-1] & broken[1:]
                       & (np.sign(residual[:-1]) == -np.sign(residual[1:])))
    return misplaced
