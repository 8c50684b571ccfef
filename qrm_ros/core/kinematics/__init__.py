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
Exact kinematics of the modified quick-return mechanism: its public names, gathered.

The chain is input shaft -> offset yoke coupling -> flywheel -> crank pin -> slotted lever
-> ram (doc/mechanism.md). Each question has a module of its own; this one names them all,
so ``from qrm_ros.core import kinematics as kin`` reaches every answer:

* the drive's dimensions and the offset's range: qrm_ros.core.geometry;
* every joint's exact state, the coupling's inverse, the reversals:
  qrm_ros.core.mechanism_state;
* stroke times, time ratio and mid-stroke speed ratio: qrm_ros.core.stroke_timing;
* the largest ram speeds of each stroke: qrm_ros.core.peak_speeds (compiled for large
  sweeps in qrm_ros.core.peak_kernel);
* every figure of steady running at once: qrm_ros.core.steady_figures;
* the offset for a wanted ratio or peak cutting speed: qrm_ros.core.offset_inverses;
* the mean cutting speed and its inverse: qrm_ros.core.cutting_speeds.

For a positive input speed the slow stroke, which moves the ram toward -x (ram velocity
< 0), is the cutting stroke; running in reverse makes the cut the fast stroke (TR < 1).
"""

from qrm_ros.core.cutting_speeds import mean_cutting_speed, offset_for_mean_cutting_speed
from qrm_ros.core.geometry import (ArrayLike, check_offset, FloatOrArray, Geometry,
                                   KinematicsError, MechanismState, SAFE_OFFSET_FRACTION)
from qrm_ros.core.mechanism_state import (input_angle_for_flywheel_angle,
                                          reversal_flywheel_angles, state)
from qrm_ros.core.offset_inverses import (offset_for_cutting_speed, offset_for_speed_ratio,
                                          offset_for_time_ratio)
from qrm_ros.core.peak_speeds import peak_ram_speeds, peak_speed_ratio
from qrm_ros.core.steady_figures import steady_theory, SteadyTheory
from qrm_ros.core.stroke_timing import (speed_ratio, speed_ratio_eq25, stroke_times,
                                        time_ratio, time_ratio_rk4)

__all__ = [
    'ArrayLike', 'FloatOrArray', 'Geometry', 'KinematicsError', 'MechanismState',
    'SAFE_OFFSET_FRACTION', 'SteadyTheory', 'check_offset', 'input_angle_for_flywheel_angle',
    'mean_cutting_speed', 'offset_for_cutting_speed', 'offset_for_mean_cutting_speed',
    'offset_for_speed_ratio', 'offset_for_time_ratio', 'peak_ram_speeds', 'peak_speed_ratio',
    'reversal_flywheel_angles', 'speed_ratio', 'speed_ratio_eq25', 'state', 'steady_theory',
    'stroke_times', 'time_ratio', 'time_ratio_rk4',
]
