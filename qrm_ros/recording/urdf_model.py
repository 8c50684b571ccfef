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
URDF model of the shaper, generated from a geometry (``qrm_urdf``; no ROS needed).

The real chain is closed; a URDF is a tree. Every moving joint hangs from ``shaper_base``
and takes the value the node publishes under the same name, so with published joint values
the pins meet: ``coupling_pin`` lies on the flywheel's slot (its local x axis),
``crank_pin`` (at the published crank radius along the crank) and ``ram_block`` on the
lever's slot (its local y axis). The shipped
``urdf/qrm_shaper.urdf`` is this module's output for the default geometry (a test keeps the
two equal); regenerate it with ``qrm_urdf -o urdf/qrm_shaper.urdf``.

Numbers are written with 12 significant digits, so the file is the same on every platform
(libm may differ in the last bit) and pins meet to about 1e-13 m.
"""

import math
import os
import tempfile
from typing import Dict, NamedTuple, Optional, Tuple, TYPE_CHECKING
import xml.etree.ElementTree as ET

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics.linkage import COLOURS, linkage_sizes
from qrm_ros.core.common.names import CRANK_RADIUS_JOINT, JOINT_NAMES, MACHINE_NAME

if TYPE_CHECKING:  # the fields it reads; any object with them will do
    from qrm_ros.core.dynamics.chain import MassProperties

__all__ = ['BASE_LINK', 'ROBOT_NAME', 'URDF_FILE_NAME', 'UrdfJoint', 'urdf_joints', 'urdf_text',
           'write_urdf']

ROBOT_NAME = MACHINE_NAME
URDF_FILE_NAME = ROBOT_NAME + '.urdf'
BASE_LINK = 'shaper_base'
(INPUT_SHAFT_JOINT, FLYWHEEL_JOINT, LEVER_JOINT, RAM_JOINT,
 COUPLING_OFFSET_JOINT) = JOINT_NAMES
# URDF requires effort and velocity limits on revolute and prismatic joints; the model has
# no actuator limits on these, so they are written as effectively unbounded (N or N m, and
# m/s or rad/s).
UNBOUNDED = 1e9


class UrdfJoint(NamedTuple):
    """One joint of the model: its frame (origin in the parent, rpy 0), axis and range."""

    name: str
    kind: str  # 'fixed', 'continuous', 'revolute' or 'prismatic'
    parent: str
    child: str
    origin: Tuple[float, float, float]  # m, in the parent link's frame
    axis: Optional[Tuple[float, float, float]] = None
    limits: Optional[Tuple[float, float]] = None  # rad or m


def urdf_joints(geometry: Geometry) -> Dict[str, UrdfJoint]:
    """
    Every joint of the model, by name: the one table the URDF and the recorded transforms share.

    Moving joints take the value the node publishes under the same name; the fixed ones place
    the pins.
    """
    sizes = linkage_sizes(geometry)
    r1 = geometry.coupling_radius
    h, phase = geometry.pivot_distance, geometry.crank_phase
    half_stroke = 0.5 * float(geometry.ram_stroke)
    z_axis = (0.0, 0.0, 1.0)
    joints = [
        UrdfJoint(COUPLING_OFFSET_JOINT, 'prismatic', BASE_LINK, 'input_carriage',
                  (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), (-r1, r1)),
        UrdfJoint(INPUT_SHAFT_JOINT, 'continuous', 'input_carriage', 'input_crank',
                  (0.0, 0.0, 0.0), z_axis),
        UrdfJoint('coupling_pin_joint', 'fixed', 'input_crank', 'coupling_pin', (r1, 0.0, 0.0)),
        UrdfJoint(FLYWHEEL_JOINT, 'continuous', BASE_LINK, 'flywheel', (0.0, 0.0, 0.0), z_axis),
        # The crank pin slides along the crank (the stroke screw): its radius is a joint.
        UrdfJoint(CRANK_RADIUS_JOINT, 'prismatic', 'flywheel', 'crank_pin', (0.0, 0.0, 0.0),
                  (math.cos(phase), math.sin(phase), 0.0), (0.0, h)),
        # The lever's angle is positive toward +x, i.e. clockwise seen from +z: axis -z.
        UrdfJoint(LEVER_JOINT, 'revolute', BASE_LINK, 'lever', (0.0, -h, 0.0),
                  (0.0, 0.0, -1.0), (-sizes.max_lever_angle, sizes.max_lever_angle)),
        UrdfJoint(RAM_JOINT, 'prismatic', BASE_LINK, 'ram', (0.0, sizes.ram_line_height, 0.0),
                  (1.0, 0.0, 0.0), (-half_stroke, half_stroke)),
        UrdfJoint('ram_block_joint', 'fixed', 'ram', 'ram_block', (0.0, 0.0, 0.0)),
    ]
    return {joint.name: joint for joint in joints}


def _number(value):
    text = format(float(value), '.12g')
    return '0' if text == '-0' else text


def _vector(*values):
    return ' '.join(_number(v) for v in values)


class _Builder:
    """Small helpers over ElementTree for the URDF elements used here."""

    def __init__(self, sizes):
        self.robot = ET.Element('robot', name=ROBOT_NAME)
        self.sizes = sizes
        for name, rgba in COLOURS.items():
            material = ET.SubElement(self.robot, 'material', name=name)
            ET.SubElement(material, 'color', rgba=_vector(*rgba))

    def link(self, name):
        return ET.SubElement(self.robot, 'link', name=name)

    def visual(self, link, shape, material, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)):
        """Add a visual; shape is ('box', (x, y, z)) or ('cylinder', (radius, length))."""
        visual = ET.SubElement(link, 'visual')
        ET.SubElement(visual, 'origin', xyz=_vector(*xyz), rpy=_vector(*rpy))
        geometry = ET.SubElement(visual, 'geometry')
        kind, dimensions = shape
        if kind == 'box':
            ET.SubElement(geometry, 'box', size=_vector(*dimensions))
        else:
            ET.SubElement(geometry, 'cylinder', radius=_number(dimensions[0]),
                          length=_number(dimensions[1]))
        ET.SubElement(visual, 'material', name=material)

    def bar(self, link, start, end, layer, material, width=None):
        """Add a flat bar from start to end (x, y) on a z layer (in bar widths)."""
        width = width or self.sizes.bar_width
        dx, dy = end[0] - start[0], end[1] - start[1]
        self.visual(link, ('box', (math.hypot(dx, dy), width, width)), material,
                    xyz=(0.5 * (start[0] + end[0]), 0.5 * (start[1] + end[1]),
                         layer * self.sizes.bar_width),
                    rpy=(0.0, 0.0, math.atan2(dy, dx)))

    def disc(self, link, radius, layer, material, xy=(0.0, 0.0), thickness=None):
        thickness = thickness or self.sizes.bar_width
        self.visual(link, ('cylinder', (radius, thickness)), material,
                    xyz=(xy[0], xy[1], layer * self.sizes.bar_width))

    def pin(self, link, xy=(0.0, 0.0)):
        """Add a pin through every layer, so it shows in front of what it joins."""
        self.disc(link, self.sizes.pin_radius, 0.5, 'pin_black', xy,
                  thickness=6.0 * self.sizes.bar_width)

    def joint(self, spec):
        """Add the joint of a UrdfJoint."""
        joint = ET.SubElement(self.robot, 'joint', name=spec.name, type=spec.kind)
        ET.SubElement(joint, 'origin', xyz=_vector(*spec.origin), rpy='0 0 0')
        ET.SubElement(joint, 'parent', link=spec.parent)
        ET.SubElement(joint, 'child', link=spec.child)
        if spec.axis is not None:
            ET.SubElement(joint, 'axis', xyz=_vector(*spec.axis))
        if spec.limits is not None:
            ET.SubElement(joint, 'limit', lower=_number(spec.limits[0]),
                          upper=_number(spec.limits[1]), effort=_number(UNBOUNDED),
                          velocity=_number(UNBOUNDED))

    def inertial(self, link, mass, inertia_zz, xyz=(0.0, 0.0, 0.0)):
        """
        Planar mass properties: only izz (about the centre of mass) is modelled.

        The out-of-plane moments are not part of the model and are written as 0.
        """
        inertial = ET.SubElement(link, 'inertial')
        ET.SubElement(inertial, 'origin', xyz=_vector(*xyz), rpy='0 0 0')
        ET.SubElement(inertial, 'mass', value=_number(mass))
        ET.SubElement(inertial, 'inertia', ixx='0', ixy='0', ixz='0', iyy='0', iyz='0',
                      izz=_number(inertia_zz))


def _lever_inertia_about_centre(mass_properties):
    """J3 is about the pivot and includes the mass (design note): remove m3 l3^2."""
    centre = (mass_properties.lever_inertia
              - mass_properties.lever_mass * mass_properties.lever_com_distance ** 2)
    if not centre >= 0.0:
        raise ValueError(
            f'lever_inertia ({mass_properties.lever_inertia!r} kg m^2) must be at least '
            'lever_mass * lever_com_distance^2 '
            f'({mass_properties.lever_mass * mass_properties.lever_com_distance ** 2!r} kg m^2)'
            ': it is about the pivot and includes the lever mass')
    return centre


def urdf_text(geometry: Geometry, mass_properties: Optional['MassProperties'] = None) -> str:
    """
    Return the URDF (XML text) of the machine with this geometry.

    ``mass_properties`` (an object with the fields of ``qrm_ros.core.dynamics.MassProperties``:
    input_inertia, flywheel_inertia, lever_inertia, lever_mass, lever_com_distance,
    ram_mass) adds inertial tags: izz J1 on the input crank and J2 on the flywheel (their
    mass is not modelled; their centres stay on their axes, so it is written as 0), the
    lever's mass at lever_com_distance with J3 moved to that centre, the ram's mass.
    Without it the URDF is kinematic only.
    """
    sizes = linkage_sizes(geometry)
    r1, r = geometry.coupling_radius, geometry.crank_radius
    h, phase = geometry.pivot_distance, geometry.crank_phase
    build = _Builder(sizes)
    joints = urdf_joints(geometry)
    width = sizes.bar_width

    # Fixed frame: column from the flywheel axis down to the lever pivot, bearings, ram
    # guide (behind everything, layer -2).
    base = build.link(BASE_LINK)
    build.bar(base, (0.0, 0.0), (0.0, -h), -2, 'frame_grey')
    build.disc(base, 2.0 * sizes.pin_radius, -2, 'frame_grey')
    build.disc(base, 2.0 * sizes.pin_radius, -2, 'frame_grey', xy=(0.0, -h))
    guide = 0.5 * (float(geometry.ram_stroke) + sizes.ram_length)
    guide_y = sizes.ram_line_height + 0.5 * (sizes.ram_thickness + width)
    build.bar(base, (-guide, guide_y), (guide, guide_y), -2, 'frame_grey')

    # The input shaft's carriage, moved along y by the offset actuator.
    carriage = build.link('input_carriage')
    build.disc(carriage, 2.0 * sizes.pin_radius, 1, 'frame_grey')
    build.joint(joints[COUPLING_OFFSET_JOINT])

    input_crank = build.link('input_crank')
    build.disc(input_crank, sizes.pin_radius * 1.6, 1, 'input_orange')
    build.bar(input_crank, (0.0, 0.0), (r1, 0.0), 1, 'input_orange')
    build.joint(joints[INPUT_SHAFT_JOINT])
    coupling_pin = build.link('coupling_pin')
    build.pin(coupling_pin)
    build.joint(joints['coupling_pin_joint'])

    # Flywheel (bull gear) with the coupling's radial slot along its local x axis and the
    # crank at the crank phase.
    flywheel = build.link('flywheel')
    build.disc(flywheel, sizes.flywheel_radius, -1, 'flywheel_blue')
    build.bar(flywheel, (0.0, 0.0), (sizes.slot_length, 0.0), 0, 'slot_black',
              width=0.6 * width)
    build.bar(flywheel, (0.0, 0.0), (r * math.cos(phase), r * math.sin(phase)), 0,
              'flywheel_blue')
    build.joint(joints[FLYWHEEL_JOINT])
    crank_pin = build.link('crank_pin')
    build.pin(crank_pin)
    build.joint(joints[CRANK_RADIUS_JOINT])

    # Slotted lever along its local +y (its joint turns about -z: see urdf_joints).
    lever = build.link('lever')
    build.bar(lever, (0.0, 0.0), (0.0, sizes.lever_length), 2, 'lever_green')
    build.joint(joints[LEVER_JOINT])

    # Ram on its line, H above the pivot; the tool hangs from its front (-x) end.
    ram = build.link('ram')
    build.visual(ram, ('box', (sizes.ram_length, sizes.ram_thickness, width)), 'ram_red',
                 xyz=(0.0, 0.0, 3 * width))
    front = -0.5 * sizes.ram_length
    build.bar(ram, (front, 0.0), (front, -sizes.tool_drop), 3, 'tool_yellow')
    build.joint(joints[RAM_JOINT])
    ram_block = build.link('ram_block')
    build.pin(ram_block)
    build.joint(joints['ram_block_joint'])

    if mass_properties is not None:
        build.inertial(input_crank, 0.0, mass_properties.input_inertia)
        build.inertial(flywheel, 0.0, mass_properties.flywheel_inertia)
        build.inertial(lever, mass_properties.lever_mass,
                       _lever_inertia_about_centre(mass_properties),
                       xyz=(0.0, mass_properties.lever_com_distance, 0.0))
        build.inertial(ram, mass_properties.ram_mass, 0.0)

    ET.indent(build.robot)
    return ('<?xml version="1.0"?>\n'
            '<!-- Generated by qrm_urdf (qrm_ros.recording.urdf_model) from the geometry: r1 = '
            f'{_number(r1)} m, r = {_number(r)} m, h = {_number(h)} m, H = '
            f'{_number(geometry.ram_height)} m, crank phase = {_number(phase)} rad. '
            'Do not edit: regenerate. -->\n'
            + ET.tostring(build.robot, encoding='unicode') + '\n')


def write_urdf(path: str, geometry: Geometry,
               mass_properties: Optional['MassProperties'] = None) -> None:
    """Write the URDF atomically (a temporary file renamed), so no half file is left."""
    text = urdf_text(geometry, mass_properties)
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(dir=folder, prefix='.' + os.path.basename(path))
    try:
        os.fchmod(handle, 0o644)  # mkstemp's 0600 would hide the model from other users
        with os.fdopen(handle, 'w') as output:
            output.write(text)
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise
