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
The one list of what qrm_ros.core.kinematics exports, and from where.

lazy_loader reads it at run time (each name loads with its module on first use); type
checkers read it as the package's interface (``name as name``: a stub's import re-exports
only in that form).
"""

from .cutting_speeds import (mean_cutting_speed as mean_cutting_speed,
                             offset_for_mean_cutting_speed as offset_for_mean_cutting_speed)
from .geometry import (ArrayLike as ArrayLike, check_offset as check_offset,
                       FloatOrArray as FloatOrArray, Geometry as Geometry,
                       KinematicsError as KinematicsError, MechanismState as MechanismState,
                       SAFE_OFFSET_FRACTION as SAFE_OFFSET_FRACTION)
from .mechanism_state import (input_angle_for_flywheel_angle as input_angle_for_flywheel_angle,
                              reversal_flywheel_angles as reversal_flywheel_angles, state as state)
from .offset_inverses import (offset_for_cutting_speed as offset_for_cutting_speed,
                              offset_for_speed_ratio as offset_for_speed_ratio,
                              offset_for_time_ratio as offset_for_time_ratio)
from .peak_speeds import (peak_ram_speeds as peak_ram_speeds, peak_speed_ratio as peak_speed_ratio)
from .steady_figures import (steady_theory as steady_theory, SteadyTheory as SteadyTheory)
from .stroke_timing import (speed_ratio as speed_ratio, speed_ratio_eq25 as speed_ratio_eq25,
                            stroke_times as stroke_times, time_ratio as time_ratio,
                            time_ratio_rk4 as time_ratio_rk4)
