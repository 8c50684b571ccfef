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
The drawn linkage: its points satisfy the mechanism's closure constraints (checked as
constraints, not by re-running the formulas), vectorised, and the drawn parts never collide.
"""

import math

import numpy as np
import pytest

from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.linkage import linkage_points, linkage_sizes, workpiece_span

GEOMETRIES = [kin.Geometry.paper(),
              kin.Geometry(0.03, 0.07, 0.16, ram_height=0.35, crank_phase=0.4),
              kin.Geometry(0.02, 0.01, 0.12, ram_height=0.15, crank_phase=-2.0)]


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _dot(a, b):
    return np.sum(a * b, axis=-1)


@pytest.mark.parametrize('geometry', GEOMETRIES, ids=['paper', 'phased', 'short_stroke'])
def test_points_close_the_chain(geometry):
    rng = np.random.default_rng(3)
    angles = rng.uniform(-30.0, 30.0, 4000)
    offsets = rng.uniform(-0.99, 0.99, angles.size) * geometry.coupling_radius
    p = linkage_points(geometry, offsets, angles)
    r1, r = geometry.coupling_radius, geometry.crank_radius
    h, height = geometry.pivot_distance, geometry.ram_height
    tolerance = 1e-15
    # Fixed and moving centres.
    assert np.allclose(p.flywheel_centre, 0.0, atol=0)
    assert np.allclose(p.lever_pivot, (0.0, -h), atol=0)
    assert np.array_equal(p.input_centre[:, 0], np.zeros_like(offsets))
    assert np.array_equal(p.input_centre[:, 1], offsets)
    # The coupling pin: r1 from O1, on the slot from O2, on its outward side.
    assert np.allclose(np.linalg.norm(p.coupling_pin - p.input_centre, axis=-1), r1,
                       rtol=0, atol=tolerance)
    slot = p.slot_end - p.flywheel_centre
    assert np.max(np.abs(_cross(slot, p.coupling_pin) / np.linalg.norm(slot, axis=-1))) \
        < tolerance
    assert np.all(_dot(slot, p.coupling_pin) > 0)
    assert np.all(np.linalg.norm(p.coupling_pin, axis=-1) < np.linalg.norm(slot, axis=-1))
    # The crank pin: r from O2, at the crank phase from the slot.
    assert np.allclose(np.linalg.norm(p.crank_pin, axis=-1), r, rtol=0, atol=tolerance)
    phase = np.arctan2(_cross(slot, p.crank_pin), _dot(slot, p.crank_pin))
    assert np.allclose(np.remainder(phase - geometry.crank_phase + math.pi, 2 * math.pi),
                       math.pi, rtol=0, atol=1e-12)
    # Crank pin and ram block on the lever (O3 -> tip), the block on the ram line.
    lever = p.lever_tip - p.lever_pivot
    unit = lever / np.linalg.norm(lever, axis=-1)[..., None]
    for pin in (p.crank_pin, p.ram_block):
        assert np.max(np.abs(_cross(unit, pin - p.lever_pivot))) < 1e-15
        assert np.all(_dot(unit, pin - p.lever_pivot) > 0)
    assert np.array_equal(p.ram_block[:, 1], np.full(angles.size, height - h))
    # ... and the block lies on the lever, short of its tip.
    assert np.all(_dot(unit, p.ram_block - p.lever_pivot) < np.linalg.norm(lever, axis=-1))


def test_points_broadcast_like_the_core():
    geometry = kin.Geometry.paper()
    grid = linkage_points(geometry, np.array([[-0.01], [0.0], [0.01]]), np.linspace(0, 6, 7))
    assert grid.coupling_pin.shape == (3, 7, 2)
    assert grid.lever_pivot.shape == (3, 7, 2)
    single = linkage_points(geometry, 0.01, 2.0)
    assert single.coupling_pin.shape == (2,)
    assert np.array_equal(single.crank_pin, grid.crank_pin[2, 2])
    state = kin.state(geometry, 0.01, 2.0, 5.0)
    assert np.array_equal(linkage_points(geometry, 0.01, 2.0, state).tool_tip, single.tool_tip)


@pytest.mark.parametrize('geometry', GEOMETRIES, ids=['paper', 'phased', 'short_stroke'])
def test_drawn_parts_do_not_collide(geometry):
    sizes = linkage_sizes(geometry)
    angles = np.linspace(0, 2 * math.pi, 2001)
    p = linkage_points(geometry, 0.0, angles)
    # The tool, at the ram's front, stays clear of the flywheel at every ram position.
    assert np.all(p.tool_tip[:, 0] < -sizes.flywheel_radius)
    # The lever reaches past the ram block at full swing.
    assert np.all(np.linalg.norm(p.ram_block - p.lever_pivot, axis=-1) < sizes.lever_length)
    assert sizes.max_lever_angle == pytest.approx(
        np.max(np.abs(kin.state(geometry, 0.0, angles, 1.0).lever_angle)), abs=1e-6)


def test_workpiece_span_is_where_the_tool_cuts():
    geometry = kin.Geometry.paper()
    cutting_length = 0.12
    low, high = workpiece_span(geometry, cutting_length)
    angles = np.linspace(0, 2 * math.pi, 200001)
    p = linkage_points(geometry, 0.0, angles)
    ram = kin.state(geometry, 0.0, angles, 1.0).ram_position
    inside = np.abs(ram) <= cutting_length / 2
    assert np.min(p.tool_tip[inside, 0]) == pytest.approx(low, abs=1e-6)
    assert np.max(p.tool_tip[inside, 0]) == pytest.approx(high, abs=1e-6)
    assert high - low == pytest.approx(cutting_length, abs=1e-15)
