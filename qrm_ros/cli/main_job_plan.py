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
The main job's short-stroke experiment, one plan for the live run and the offline one.

After the offset schedule the stroke is shortened to the paper's short stroke with the
offset at 0 (the time ratio falls toward 1), then the long stroke's time ratio at offset 0
is held by the offset (``time_ratio_target``).
"""

import math
from typing import NamedTuple

from qrm_ros.core import kinematics as kin
from qrm_ros.core.stepping.stroke_adjustment import largest_stroke
from qrm_ros.node.main_job.main_job_conductor import MainJobError

__all__ = ['SHORT_STROKE_MM', 'ShortStroke', 'short_stroke_plan', 'STROKE_RATE_LIMIT',
           'UsageError']

SHORT_STROKE_MM = 60.0  # the paper's short stroke, where offset 0 loses the quick return
SHORT_STROKE_SLOT = 0.07  # m: shaper_sim's default max_crank_radius
SHORT_WORKPIECE_SHARE = 0.8  # the workpiece at the short stroke, as a share of it
STROKE_RATE_LIMIT = 0.1  # m/s: the stroke screw, fast enough for a short job


class UsageError(MainJobError):
    """An option outside what the job accepts (exit code 2)."""


class ShortStroke(NamedTuple):
    stroke: float  # m, the ram stroke
    workpiece: float  # m, the cutting length at it
    time_ratio: float  # the long stroke's at offset 0, held at the short one


def short_stroke_plan(short_stroke_mm: float, cutting_length: float) -> ShortStroke:
    """Return the short-stroke experiment at this stroke (mm); UsageError if refused."""
    geometry = kin.Geometry.paper()
    stroke = short_stroke_mm / 1e3
    largest = largest_stroke(geometry, SHORT_STROKE_SLOT)
    if not (math.isfinite(stroke) and 0.0 < stroke <= largest):
        raise UsageError(f'--short-stroke-mm must be in (0, {largest * 1e3:.6g}] mm (the '
                         f"slot of shaper_sim's max_crank_radius) or 0, got "
                         f'{short_stroke_mm:g}')
    # The workpiece shortened to fit the stroke; the long stroke's time ratio at offset 0.
    return ShortStroke(stroke, min(cutting_length, SHORT_WORKPIECE_SHARE * stroke),
                       float(kin.time_ratio(geometry, 0.0)))
