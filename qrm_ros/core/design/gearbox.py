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
Gearbox planner: the fewest gear steps that, with the offset, reach every cutting speed.

The paper's economic claim ("four speeds instead of five"), made checkable. Pure numpy/scipy.

Derivation. At a fixed offset d the cutting speed, mean or peak, is proportional to the
input speed n: v = u(d) n (u in m/rad). The usable offsets, |d| <= D and TR(d) >= R, form
an interval, since TR is monotone in d; u is continuous on it, so it takes every value of
[u_lo, u_hi] there. A step at input speed n therefore reaches exactly the band
[u_lo n, u_hi n], whose ratio q = u_hi / u_lo does not depend on n. Bands of N steps can
cover [V1, V2] only if their lengths on a log scale add up, N log q >= log(V2 / V1), for any
set of steps, geometric or not: N = ceil(log(V2 / V1) / log q) is the fewest. A geometric
progression reaches it: ratio phi = (V2 / V1)^(1/N) <= q, step k (from 0) runs at
n_k = V1 phi^(k + 1/2) / sqrt(u_lo u_hi) and serves [V1 phi^k, V1 phi^(k + 1)], the middle of
its reach on a log scale, with a margin of sqrt(q / phi) either side for the handover. So the
lowest input speed and phi are fixed by V1, V2 and N; the largest usable phi is q itself.

Without the offset (d = 0) a step gives one speed, u(0) n_k; a wanted speed V is cut at the
fastest step not above it, short of V by at most 1 - 1/phi. Steps V1 phi^k cover [V1, V2]
that way with N0 = ceil(log(V2 / V1) / log phi) steps, for the standard progression ratios.
"""

import math
from typing import Callable, cast, NamedTuple, Optional, Tuple

import numpy as np
from scipy import optimize
from scipy.optimize import elementwise

from qrm_ros.core.common.checks import as_float, KinematicsError
from qrm_ros.core.kinematics.cutting_speeds import mean_cutting_speed
from qrm_ros.core.kinematics.geometry import ArrayLike, FloatOrArray, Geometry
from qrm_ros.core.kinematics.offset_inverses import offset_for_time_ratio
from qrm_ros.core.kinematics.peak_speeds import peak_ram_speeds
from qrm_ros.core.numerics.portable_math import power
from qrm_ros.core.kinematics.stroke_timing import time_ratio

__all__ = ['ConventionalGearbox', 'DEFAULT_MIN_TIME_RATIO', 'DEFINITIONS', 'GearStep',
           'GearboxPlan', 'MAX_STEPS', 'OffsetRange', 'STANDARD_PROGRESSION_RATIOS',
           'conventional_gearbox', 'fewest_steps', 'offset_range', 'offsets_for_unit_speeds',
           'plan_as_dict', 'plan_gearbox', 'unit_cutting_speed', 'usable_offsets']

# Progression ratios of machine-tool gearboxes (Renard series R20/2 ... R10/3 and 2).
STANDARD_PROGRESSION_RATIOS = (1.12, 1.26, 1.41, 1.58, 2.0)
DEFINITIONS = ('mean', 'peak')
DEFAULT_MIN_TIME_RATIO = 1.0
# A gearbox with more steps than this is no answer; the message says what limits the band.
MAX_STEPS = 100
# Offsets sampled over the usable interval to bracket the band's ends before refining.
_BAND_SAMPLES = 401
# Relative rounding error tolerated where a band end meets the edge of the offsets' reach.
_ROUNDING = 1e-12


class OffsetRange(NamedTuple):
    """The usable offsets (m) and the cutting speed per input speed (m/rad) they give."""

    offset_min: float
    offset_max: float
    offset_at_slowest: float
    offset_at_fastest: float
    slowest_per_input_speed: float
    fastest_per_input_speed: float


class GearStep(NamedTuple):
    """One gear step: input speed (rad/s), the band of cutting speeds (m/s) it serves."""

    input_speed: float
    cutting_speed_min: float
    cutting_speed_max: float
    offset_at_min: float
    offset_at_max: float


class ConventionalGearbox(NamedTuple):
    """A geometric gearbox without offset: its steps and largest shortfall (fraction)."""

    progression_ratio: float
    max_shortfall: float
    step_count: int
    input_speeds: Tuple[float, ...]
    cutting_speeds: Tuple[float, ...]


class GearboxPlan(NamedTuple):
    """The fewest steps with the offset, and the conventional gearboxes beside them."""

    definition: str
    min_cutting_speed: float
    max_cutting_speed: float
    max_offset: float
    min_time_ratio: float
    offsets: OffsetRange
    band_ratio: float
    progression_ratio: float
    steps: Tuple[GearStep, ...]
    conventional: Tuple[ConventionalGearbox, ...]


def unit_cutting_speed(geometry: Geometry,
                       definition: str) -> Callable[[ArrayLike], FloatOrArray]:
    """Cutting speed per unit input speed (m/rad) as a vectorised function of the offset."""
    if definition == 'mean':
        return lambda offset: mean_cutting_speed(geometry, offset, 1.0)
    if definition == 'peak':
        return lambda offset: peak_ram_speeds(geometry, offset, 1.0)[0]
    raise KinematicsError(
        f'definition must be one of {", ".join(DEFINITIONS)}, got {definition!r}')


def _positive(name, value, unit):
    value = as_float(name, value)
    if np.ndim(value) or value <= 0.0:
        raise KinematicsError(f'{name} must be one number > 0{unit}, got {value!r}')
    return value


def usable_offsets(geometry: Geometry, max_offset: float,
                   min_time_ratio: float) -> Tuple[float, float]:
    """Return the interval of offsets with |offset| <= max_offset and TR >= min_time_ratio."""
    ends = (-max_offset, max_offset)
    ratios = [time_ratio(geometry, end) for end in ends]
    quick = [ratio >= min_time_ratio for ratio in ratios]
    if not any(quick):
        raise KinematicsError(
            f'min_time_ratio {min_time_ratio:g} is out of reach: offsets with |offset| <= '
            f'{max_offset:g} m give TR from {min(ratios):.6g} to {max(ratios):.6g}')
    if all(quick):
        return ends
    # TR is monotone in the offset, so one end qualifies and the limit lies between.
    limit = float(offset_for_time_ratio(geometry, min_time_ratio))
    return (limit, max_offset) if quick[1] else (-max_offset, limit)


def _extreme_offset(function, low, high, sign):
    """Offset in [low, high] where sign * function is largest (sampled, then refined)."""
    grid = np.linspace(low, high, _BAND_SAMPLES)
    values = sign * np.asarray(function(grid))
    best = int(np.argmax(values))
    if best in (0, len(grid) - 1):
        return float(grid[best])
    found = optimize.minimize_scalar(lambda d: -sign * float(function(d)), method='bounded',
                                     bounds=(grid[best - 1], grid[best + 1]),
                                     options={'xatol': 1e-15})
    return float(found.x) if -found.fun > values[best] else float(grid[best])


def offset_range(geometry: Geometry, definition: str, max_offset: float,
                 min_time_ratio: float) -> OffsetRange:
    """Usable offsets and the slowest and fastest cutting speed per input speed they give."""
    function = unit_cutting_speed(geometry, definition)
    low, high = usable_offsets(geometry, max_offset, min_time_ratio)
    slow = _extreme_offset(function, low, high, -1.0)
    fast = _extreme_offset(function, low, high, 1.0)
    return OffsetRange(low, high, slow, fast, float(function(slow)), float(function(fast)))


def offsets_for_unit_speeds(geometry: Geometry, definition: str, offsets: OffsetRange,
                            unit_speeds: np.ndarray) -> np.ndarray:
    """
    Offsets (m) giving cutting speeds per input speed within the range; vectorised.

    Solved between the offsets of the slowest and fastest speed, where a root exists.
    """
    function = unit_cutting_speed(geometry, definition)
    low, high = offsets.slowest_per_input_speed, offsets.fastest_per_input_speed
    targets = np.asarray(unit_speeds, dtype=float)
    # Band ends computed from phi = q may stray past the range by a rounding error.
    assert np.all(targets >= low * (1 - 2 * _ROUNDING))
    assert np.all(targets <= high * (1 + 2 * _ROUNDING))
    targets = np.clip(targets, low, high)
    bracket = sorted((offsets.offset_at_slowest, offsets.offset_at_fastest))
    result = elementwise.find_root(
        lambda d, target: function(d) - target,
        (np.full(targets.shape, bracket[0]), np.full(targets.shape, bracket[1])),
        args=(targets,), tolerances={'xatol': 1e-17, 'xrtol': 4 * np.finfo(float).eps})
    return result.x


def fewest_steps(range_ratio: float, step_ratio: float) -> int:
    """
    Smallest N with step_ratio^N >= range_ratio (both > 1): N bands cover the range.

    A range that is an exact power of the step ratio may come out a rounding error above
    it; it still counts as covered (_ROUNDING).
    """
    needed = range_ratio * (1.0 - _ROUNDING)
    count = max(1, math.ceil(math.log(needed) / math.log(step_ratio)))
    while count > 1 and step_ratio ** (count - 1) >= needed:
        count -= 1
    while step_ratio ** count < needed:
        count += 1
    return count


def conventional_gearbox(geometry: Geometry, definition: str, min_cutting_speed: float,
                         max_cutting_speed: float,
                         progression_ratio: float) -> ConventionalGearbox:
    """Plan steps V1 phi^k without offset: each wanted speed cut at most 1 - 1/phi slower."""
    progression_ratio = _positive('progression_ratio', progression_ratio, '')
    if progression_ratio <= 1.0:
        raise KinematicsError(
            f'progression_ratio must be > 1, got {progression_ratio!r}')
    count = fewest_steps(max_cutting_speed / min_cutting_speed, progression_ratio)
    speeds = min_cutting_speed * power(progression_ratio, np.arange(count))
    unit = float(unit_cutting_speed(geometry, definition)(0.0))
    return ConventionalGearbox(progression_ratio, 1.0 - 1.0 / progression_ratio, count,
                               tuple(float(v) for v in speeds / unit),
                               tuple(float(v) for v in speeds))


def plan_gearbox(geometry: Geometry, min_cutting_speed: float, max_cutting_speed: float,
                 definition: str = 'mean', max_offset: Optional[float] = None,
                 min_time_ratio: float = DEFAULT_MIN_TIME_RATIO,
                 progression_ratios: Tuple[float, ...] = STANDARD_PROGRESSION_RATIOS
                 ) -> GearboxPlan:
    """
    Fewest geometric gear steps reaching every cutting speed in [min, max] (m/s) exactly.

    max_offset (m) defaults to the node's limit, geometry.max_safe_offset; the planner
    assumes forward running (positive input speeds), where the cut is the slow stroke.
    """
    unit_cutting_speed(geometry, definition)  # refuses an unknown definition first
    v1 = _positive('min_cutting_speed', min_cutting_speed, ' m/s')
    v2 = _positive('max_cutting_speed', max_cutting_speed, ' m/s')
    if v1 >= v2:
        raise KinematicsError(
            f'min_cutting_speed ({v1:g} m/s) must be below max_cutting_speed ({v2:g} m/s)')
    # One number (cast for the type checker): an array is refused just below.
    max_offset = cast(float, as_float(
        'max_offset', geometry.max_safe_offset if max_offset is None else max_offset))
    if np.ndim(max_offset) or not 0.0 <= max_offset < geometry.coupling_radius:
        raise KinematicsError(
            f'max_offset must be >= 0 and < coupling_radius = {geometry.coupling_radius:g} m,'
            f' got {max_offset!r}')
    min_time_ratio = _positive('min_time_ratio', min_time_ratio, '')
    offsets = offset_range(geometry, definition, max_offset, min_time_ratio)
    band_ratio = offsets.fastest_per_input_speed / offsets.slowest_per_input_speed
    range_ratio = v2 / v1
    allowed = f'the offsets allowed (|offset| <= {max_offset:g} m, TR >= {min_time_ratio:g})'
    remedy = 'allow a larger max_offset or a lower min_time_ratio'
    if band_ratio <= 1.0 + 1e-9:
        raise KinematicsError(
            f'{allowed} leave one {definition} cutting speed per step (band ratio '
            f'{band_ratio:.9g}), so no gearbox reaches every speed from {v1:g} to {v2:g} m/s '
            f'exactly; {remedy}')
    if math.log(range_ratio) / math.log(band_ratio) > MAX_STEPS:
        raise KinematicsError(
            f'{allowed} change the {definition} cutting speed by a factor of only '
            f'{band_ratio:.9g}: more than {MAX_STEPS} steps would be needed to reach every '
            f'speed from {v1:g} to {v2:g} m/s; {remedy}')
    count = fewest_steps(range_ratio, band_ratio)
    progression = min(range_ratio ** (1.0 / count), band_ratio)
    edges = v1 * power(progression, np.arange(count + 1))
    edges[-1] = v2
    centre = math.sqrt(offsets.slowest_per_input_speed * offsets.fastest_per_input_speed)
    input_speeds = v1 * power(progression, np.arange(count) + 0.5) / centre
    ends = offsets_for_unit_speeds(
        geometry, definition, offsets,
        np.stack([edges[:-1] / input_speeds, edges[1:] / input_speeds]))
    steps = tuple(GearStep(float(input_speeds[k]), float(edges[k]), float(edges[k + 1]),
                           float(ends[0, k]), float(ends[1, k])) for k in range(count))
    conventional = tuple(conventional_gearbox(geometry, definition, v1, v2, ratio)
                         for ratio in progression_ratios)
    return GearboxPlan(definition, v1, v2, float(max_offset), min_time_ratio, offsets,
                       float(band_ratio), float(progression), steps, conventional)


def plan_as_dict(plan: GearboxPlan, geometry: Geometry) -> dict:
    """Return the plan as plain JSON types, SI units; keys documented in the README."""
    result = plan._asdict()
    result['geometry'] = {name: float(value) for name, value in geometry.as_dict().items()}
    result['offsets'] = plan.offsets._asdict()
    result['steps'] = [step._asdict() for step in plan.steps]
    result['conventional'] = [dict(box._asdict(), input_speeds=list(box.input_speeds),
                                   cutting_speeds=list(box.cutting_speeds))
                              for box in plan.conventional]
    return result
