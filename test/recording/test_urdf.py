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
The URDF: generated from the geometry, shipped unchanged, and with published joint values
its open tree closes (checked with yourdfpy's forward kinematics, not our own).
"""

from collections import namedtuple
import dataclasses
import math
import os

from ament_index_python.packages import get_package_share_directory
import numpy as np
import pytest

from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import PUBLISHED_JOINT_NAMES
from qrm_ros.cli.qrm_urdf import main
from qrm_ros.recording.urdf_model import BASE_LINK, URDF_FILE_NAME, urdf_text, write_urdf
from repo_paths import REPO_ROOT

yourdfpy = pytest.importorskip('yourdfpy')

SHIPPED = os.path.join(REPO_ROOT, 'urdf', URDF_FILE_NAME)
GEOMETRIES = {
    'paper': kin.Geometry.paper(),
    'phased': kin.Geometry(0.03, 0.07, 0.16, ram_height=0.35, crank_phase=0.4),
    'short_stroke': kin.Geometry(0.02, 0.01, 0.12, ram_height=0.15, crank_phase=-2.0),
}
# The design note's check parameters (doc/dynamics.md).
MassProperties = namedtuple('MassProperties', 'input_inertia flywheel_inertia lever_inertia '
                                              'lever_mass lever_com_distance ram_mass')
CHECK_MASS = MassProperties(0.01, 0.5, 0.3, 8.0, 0.15, 20.0)


def _load(geometry, mass_properties=None, tmp_path=None):
    path = os.path.join(tmp_path, 'model.urdf')
    write_urdf(path, geometry, mass_properties)
    return yourdfpy.URDF.load(path, build_scene_graph=True, load_meshes=False)


def _wrapped(angle):
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi


def _configure(model, geometry, offset, input_angle):
    """Set the joints to what the node publishes for this state (angles wrapped)."""
    state = kin.state(geometry, offset, input_angle, 1.0)
    values = {'input_shaft_joint': _wrapped(input_angle),
              'flywheel_joint': _wrapped(state.flywheel_angle),
              'lever_joint': state.lever_angle, 'ram_joint': state.ram_position,
              'coupling_offset_joint': offset, 'crank_radius_joint': geometry.crank_radius}
    model.update_cfg({name: float(values[name]) for name in PUBLISHED_JOINT_NAMES})
    return state


def _position(model, frame, in_frame=BASE_LINK):
    return model.get_transform(frame, in_frame)[:3, 3]


def test_shipped_urdf_is_the_generated_one():
    expected = urdf_text(kin.Geometry.paper())
    with open(SHIPPED) as handle:
        assert handle.read() == expected, \
            'urdf/qrm_shaper.urdf is stale: regenerate it with qrm_urdf -o urdf/qrm_shaper.urdf'


def test_installed_urdf_is_found_through_the_ament_index():
    path = os.path.join(get_package_share_directory('qrm_ros'), 'urdf', URDF_FILE_NAME)
    with open(path) as handle:
        assert handle.read() == urdf_text(kin.Geometry.paper())


def test_joints_links_axes_and_limits(tmp_path):
    geometry = GEOMETRIES['paper']
    model = _load(geometry, tmp_path=str(tmp_path))
    assert model.robot.name == 'qrm_shaper'
    assert model.base_link == BASE_LINK
    assert sorted(model.actuated_joint_names) == sorted(PUBLISHED_JOINT_NAMES)
    joints = model.joint_map
    expected = {
        'coupling_offset_joint': ('prismatic', (0, 1, 0), BASE_LINK),
        'input_shaft_joint': ('continuous', (0, 0, 1), 'input_carriage'),
        'flywheel_joint': ('continuous', (0, 0, 1), BASE_LINK),
        'lever_joint': ('revolute', (0, 0, -1), BASE_LINK),
        'ram_joint': ('prismatic', (1, 0, 0), BASE_LINK),
        'crank_radius_joint': ('prismatic', (1, 0, 0), 'flywheel'),  # crank phase 0
    }
    for name, (kind, axis, parent) in expected.items():
        assert joints[name].type == kind
        assert np.array_equal(joints[name].axis, axis), name
        assert joints[name].parent == parent
    for child, parent in (('coupling_pin', 'input_crank'), ('ram_block', 'ram')):
        fixed = [j for j in joints.values() if j.child == child]
        assert len(fixed) == 1 and fixed[0].type == 'fixed' and fixed[0].parent == parent
    # Joint origins: O1 moves from O2 along y, O3 is h below O2, the ram line H above O3.
    h, height = geometry.pivot_distance, geometry.ram_height
    assert np.allclose(joints['lever_joint'].origin[:3, 3], (0, -h, 0), atol=1e-12)
    assert np.allclose(joints['ram_joint'].origin[:3, 3], (0, height - h, 0), atol=1e-12)
    swing = math.asin(geometry.crank_radius / h)
    assert joints['lever_joint'].limit.lower == pytest.approx(-swing, abs=1e-11)
    assert joints['lever_joint'].limit.upper == pytest.approx(swing, abs=1e-11)
    half_stroke = height * geometry.crank_radius / math.sqrt(h * h - geometry.crank_radius ** 2)
    assert joints['ram_joint'].limit.upper == pytest.approx(half_stroke, abs=1e-11)
    assert joints['coupling_offset_joint'].limit.upper == pytest.approx(
        geometry.coupling_radius, abs=1e-15)
    # Every link has something to see.
    for name, link in model.link_map.items():
        assert link.visuals, name


@pytest.mark.parametrize('name', sorted(GEOMETRIES))
def test_published_joint_values_close_the_chain(name, tmp_path):
    geometry = GEOMETRIES[name]
    model = _load(geometry, tmp_path=str(tmp_path))
    r1, r = geometry.coupling_radius, geometry.crank_radius
    h, height = geometry.pivot_distance, geometry.ram_height
    rng = np.random.default_rng(7)
    angles = np.concatenate([rng.uniform(-20.0, 20.0, 150), np.linspace(0, 2 * math.pi, 25)])
    offsets = rng.uniform(-0.95, 0.95, angles.size) * r1
    offsets[:5] = 0.0
    limits = model.joint_map['lever_joint'].limit
    worst = 0.0
    for input_angle, offset in zip(angles, offsets):
        state = _configure(model, geometry, offset, input_angle)
        # The coupling pin: on the input crank, r1 from O1 = (0, offset) ...
        pin = _position(model, 'coupling_pin')
        expected = (r1 * math.cos(input_angle), offset + r1 * math.sin(input_angle), 0.0)
        worst = max(worst, np.max(np.abs(pin - expected)))
        # ... and on the flywheel's slot: its local x axis, outward.
        in_flywheel = _position(model, 'coupling_pin', 'flywheel')
        worst = max(worst, abs(in_flywheel[1]), abs(in_flywheel[2]))
        assert in_flywheel[0] > 0.0
        # The crank pin and the ram block on the lever's slot (its local y axis).
        for frame in ('crank_pin', 'ram_block'):
            in_lever = _position(model, frame, 'lever')
            worst = max(worst, abs(in_lever[0]), abs(in_lever[2]))
            assert in_lever[1] > 0.0
        # The ram block on the ram line, H above O3.
        block = _position(model, 'ram_block')
        worst = max(worst, abs(block[1] - (height - h)))
        # The crank pin r from O2 (a check of the flywheel joint's own value).
        worst = max(worst, abs(np.hypot(*_position(model, 'crank_pin')[:2]) - r))
        assert limits.lower - 1e-12 <= state.lever_angle <= limits.upper + 1e-12
    assert worst <= 1e-9


def test_a_moved_crank_radius_keeps_the_chain_closed(tmp_path):
    """The model of one radius, driven at another (a stroke change): the pins still meet."""
    geometry = GEOMETRIES['paper']
    model = _load(geometry, tmp_path=str(tmp_path))
    for radius in (0.015, 0.03, 0.07):
        moved = dataclasses.replace(geometry, crank_radius=radius)
        for input_angle, offset in ((0.3, 0.0), (2.0, 0.01), (-2.5, -0.015)):
            _configure(model, moved, offset, input_angle)
            assert np.hypot(*_position(model, 'crank_pin')[:2]) == pytest.approx(radius,
                                                                                 abs=1e-12)
            for frame in ('crank_pin', 'ram_block'):
                in_lever = _position(model, frame, 'lever')
                assert abs(in_lever[0]) < 1e-12 and in_lever[1] > 0.0


def _mass_matrix_from_urdf(model, geometry, offset, input_angle, step=1e-5):
    """
    M = sum of m |d(centre)/d(theta)|^2 + izz (d(link angle)/d(theta))^2, from the URDF.

    Link poses from yourdfpy's forward kinematics at theta +/- step (central differences),
    masses and inertias from the URDF's inertial tags.
    """
    total = 0.0
    poses = {}
    for sign in (-1.0, 1.0):
        _configure(model, geometry, offset, input_angle + sign * step)
        for name, link in model.link_map.items():
            if link.inertial is None:
                continue
            transform = model.get_transform(name, BASE_LINK) @ link.inertial.origin
            poses.setdefault(name, []).append(
                (transform[:3, 3], math.atan2(transform[1, 0], transform[0, 0])))
    for name, ((low_position, low_angle), (high_position, high_angle)) in poses.items():
        inertial = model.link_map[name].inertial
        velocity = (high_position - low_position) / (2 * step)
        rate = math.remainder(high_angle - low_angle, 2 * math.pi) / (2 * step)
        total += inertial.mass * velocity @ velocity + inertial.inertia[2, 2] * rate ** 2
    return total


@pytest.mark.parametrize('input_angle, offset, expected', [
    (1.0, 0.01, 0.330327333115), (2.5, -0.01, 0.713528369261), (4.0, 0.015, 0.760494971453)])
def test_inertial_tags_give_the_design_notes_generalised_inertia(input_angle, offset, expected,
                                                                 tmp_path):
    model = _load(kin.Geometry.paper(), CHECK_MASS, tmp_path=str(tmp_path))
    measured = _mass_matrix_from_urdf(model, kin.Geometry.paper(), offset, input_angle)
    assert measured == pytest.approx(expected, rel=1e-7)


def test_kinematic_only_model_has_no_inertial_tags(tmp_path):
    model = _load(kin.Geometry.paper(), tmp_path=str(tmp_path))
    assert all(link.inertial is None for link in model.link_map.values())


def test_lever_inertia_smaller_than_its_mass_moment_is_refused():
    bad = CHECK_MASS._replace(lever_inertia=0.1)  # < 8 kg * (0.15 m)^2 = 0.18 kg m^2
    with pytest.raises(ValueError, match='lever_inertia'):
        urdf_text(kin.Geometry.paper(), bad)


def test_command_writes_the_model_for_a_geometry(tmp_path, capsys):
    path = tmp_path / 'phased.urdf'
    assert main(['-o', str(path), '--crank-phase', '0.4', '--ram-height', '0.35',
                 '--coupling-radius', '0.03', '--crank-radius', '0.07',
                 '--pivot-distance', '0.16']) == 0
    assert path.read_text() == urdf_text(GEOMETRIES['phased'])
    assert oct(path.stat().st_mode & 0o777) == oct(0o644)
    assert main([]) == 0
    assert capsys.readouterr().out == urdf_text(kin.Geometry.paper())


@pytest.mark.parametrize('arguments, code, words', [
    (['--crank-radius', '0.2'], 2, 'crank_radius'),
    (['--ram-height', '-1'], 2, 'ram_height must be > 0'),
    (['-o', '/nonexistent-folder/x.urdf'], 1,
     'cannot write /nonexistent-folder/x.urdf: No such file or directory'),
    (['--crank-phase', '1e300'], 2, '--crank-phase = 1e+300 rad is out of range: allowed '
                                    '[-3.14159, 3.14159] rad'),
])
def test_command_refuses_bad_input_in_one_line(arguments, code, words, capsys):
    assert main(arguments) == code
    error = capsys.readouterr().err
    assert error.startswith('qrm_urdf: error: ') and words in error
    assert error.count('\n') == 1 and 'Traceback' not in error
