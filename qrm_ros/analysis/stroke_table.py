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
The stroke table: what the stroke does to the quick return, and the offset that restores it.

Printed by ``qrm_design stroke``: for a range of ram strokes, the crank radius that gives
each, the time ratio with no offset (a short stroke loses its quick return), the offset that
restores a wanted time ratio (the exact inverse, within the node's offset safety limit) and
the flywheel's speed swing that offset costs. A JSON-ready dict in SI units first, then its
text.
"""

import dataclasses
from typing import Any, Dict, Iterable

from qrm_ros.analysis.theory import flywheel_speed_swing
from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke
from qrm_ros.core.design.time_ratio_hold import hold_time_ratio

__all__ = ['format_stroke_table', 'stroke_table_data']


def stroke_table_data(geometry: kin.Geometry, strokes: Iterable[float],
                      time_ratio: float) -> Dict[str, Any]:
    """
    Return the stroke table: per stroke (m), TR at offset 0 and the offset for time_ratio.

    geometry gives r1, h, H and the crank phase (its crank radius is replaced per stroke).
    A stroke whose crank radius is not below pivot_distance raises KinematicsError (via
    Geometry). Where no safe offset gives time_ratio, the row says so and holds the nearest.
    """
    if not time_ratio > 0.0:
        raise kin.KinematicsError(f'time ratio {time_ratio!r} is out of range: allowed > 0')
    rows = []
    for stroke in map(float, strokes):
        if not stroke > 0.0:
            raise kin.KinematicsError(f'stroke length {stroke!r} m is out of range: allowed > 0')
        radius = float(crank_radius_for_stroke(stroke, geometry.pivot_distance,
                                               geometry.ram_height))
        at_stroke = dataclasses.replace(geometry, crank_radius=radius)
        answer = hold_time_ratio(at_stroke, time_ratio)
        rows.append({
            'stroke_length': stroke, 'crank_radius': radius,
            'time_ratio_at_zero_offset': float(kin.time_ratio(at_stroke, 0.0)),
            'offset': answer.offset, 'offset_over_pivot_distance':
                answer.offset / float(geometry.pivot_distance),
            'reachable': answer.problem is None,
            'time_ratio_reached': float(kin.time_ratio(at_stroke, answer.offset)),
            'flywheel_speed_swing': flywheel_speed_swing(at_stroke, answer.offset)})
    return {'time_ratio_target': float(time_ratio), 'coupling_radius':
            float(geometry.coupling_radius), 'pivot_distance': float(geometry.pivot_distance),
            'ram_height': float(geometry.ram_height), 'rows': rows}


def format_stroke_table(data: Dict[str, Any]) -> str:
    """Return the stroke table as text (mm for lengths)."""
    lines = [
        f'time ratio wanted: {data["time_ratio_target"]:g} (forward running); r1 = '
        f'{data["coupling_radius"] * 1e3:g} mm, h = {data["pivot_distance"] * 1e3:g} mm, '
        f'H = {data["ram_height"] * 1e3:g} mm',
        '',
        ' stroke  crank r  TR at offset 0 | offset for TR  offset/h  TR there  flywheel '
        'max/min',
        '   [mm]     [mm]             [-] |          [mm]       [-]       [-]          [-]',
    ]
    for row in data['rows']:
        mark = '' if row['reachable'] else '  (out of reach: the nearest safe offset)'
        lines.append(
            f'{row["stroke_length"] * 1e3:7.1f} {row["crank_radius"] * 1e3:8.3f} '
            f'{row["time_ratio_at_zero_offset"]:15.4f} | {row["offset"] * 1e3:13.3f} '
            f'{row["offset_over_pivot_distance"]:+9.4f} {row["time_ratio_reached"]:9.4f} '
            f'{row["flywheel_speed_swing"]:12.4f}{mark}')
    return '\n'.join(lines)
