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
The main job's plan, one for the live run and the offline one.

shaper_sim's start-up values (checked by the node's own rules before anything starts), and
the short-stroke experiment.

After the offset schedule the stroke is shortened to the paper's short stroke with the
offset at 0 (the time ratio falls toward 1), then the long stroke's time ratio at offset 0
is held by the offset (``time_ratio_target``).
"""

import argparse
import math
from typing import Any, Dict, NamedTuple

from qrm_ros.core import kinematics as kin
from qrm_ros.core.stepping.stroke_adjustment import largest_stroke
from qrm_ros.node.main_job.main_job_conductor import MainJobError
from qrm_ros.node.shaper_sim.shaper_parameters import default_values, start_up_refusal

__all__ = ['check_start_up', 'SHORT_STROKE_MM', 'ShortStroke', 'short_stroke_plan',
           'start_up_parameters', 'STROKE_RATE_LIMIT', 'UsageError']

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


def start_up_parameters(options: argparse.Namespace) -> Dict[str, Any]:
    """Return the shaper_sim parameters the main job starts with, live or offline."""
    return {
        'stroke_rate_limit': STROKE_RATE_LIMIT,
        'coupling_offset': options.offsets_mm[0] / 1e3,
        'input_speed': float(options.input_speed),
        'publish_rate': float(options.publish_rate),
        'offset_rate_limit': float(options.offset_rate_limit),
        'cutting_force': float(options.cutting_force),
        'ram_friction': float(options.ram_friction),
        'cutting_length': float(options.cutting_length), 'drive': options.drive}


def check_start_up(options: argparse.Namespace) -> None:
    """Refuse what shaper_sim would refuse at start-up, by its own rules (UsageError)."""
    values = dict(default_values(), **start_up_parameters(options))
    reason = start_up_refusal(values, kin.Geometry.paper())
    if reason:
        raise UsageError(f'shaper_sim would refuse it: {reason}')
