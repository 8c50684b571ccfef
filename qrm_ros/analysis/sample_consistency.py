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
The recorded joint states judged by the physics (core.measurement.joint_consistency).

A sample that the closed form contradicts is dropped and said, with its time and the check
that caught it; a recording most of whose samples it contradicts was made with another
geometry (or is not this machine's), and is refused rather than analysed with the wrong one.
"""

from typing import List, Optional, Tuple

import numpy as np

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.measurement.joint_consistency import CONSISTENCY_CHECKS, inconsistent_samples

__all__ = ['contradicted', 'FOREIGN_FRACTION', 'foreign_geometry_problem']

# More than this fraction of the samples contradicted: not this geometry's recording.
FOREIGN_FRACTION = 0.5


def contradicted(geometry: Geometry, position: np.ndarray, velocity: np.ndarray,
                 judged: np.ndarray, crank_radius: Optional[np.ndarray] = None,
                 crank_radius_rate: Optional[np.ndarray] = None
                 ) -> List[Tuple[str, np.ndarray]]:
    """
    Return (reason, caught) per check that caught samples of a decoded block.

    position and velocity: (n, joints) in JOINT_NAMES order (input, flywheel, lever, ram,
    offset); judged: which rows to judge (the finite ones); crank_radius and its rate: the
    crank radius joint's (NaN or None: not recorded, the geometry's radius is in force).
    Each sample is caught once, by the first check it fails.
    """
    caught_any = np.zeros(judged.shape, dtype=bool)
    found: List[Tuple[str, np.ndarray]] = []
    if not judged.any():
        return found
    rows = np.flatnonzero(judged)
    failed = inconsistent_samples(
        geometry, position[rows, 0], velocity[rows, 0], position[rows, 4], velocity[rows, 4],
        position[rows, 1], velocity[rows, 1], position[rows, 3], velocity[rows, 3],
        lever_angle=position[rows, 2], lever_speed=velocity[rows, 2],
        crank_radius=None if crank_radius is None else np.asarray(crank_radius)[rows],
        crank_radius_rate=(None if crank_radius_rate is None
                           else np.asarray(crank_radius_rate)[rows]))
    for name, failing in failed.items():
        caught = np.zeros(judged.shape, dtype=bool)
        caught[rows[failing]] = True
        caught &= ~caught_any
        if caught.any():
            caught_any |= caught
            found.append((f'{CONSISTENCY_CHECKS[name]} (closed form, check {name})', caught))
    return found


def foreign_geometry_problem(path: str, geometry: Geometry, inconsistent: int,
                             used: int) -> Optional[str]:
    """Say why a run most of whose samples the closed form contradicts is refused, or None."""
    if inconsistent <= FOREIGN_FRACTION * (inconsistent + used):
        return None
    return (f'{path}: {inconsistent} of {inconsistent + used} joint states contradict the closed '
            f'form of the geometry in use ({geometry.as_dict()}): recorded with another '
            'geometry? Give it with the geometry options')
