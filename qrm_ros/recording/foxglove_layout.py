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
The Foxglove layout of a run, generated from the geometry (``qrm_urdf --foxglove-layout``).

A 3D panel that frames the machine (drawn from the recorded URDF and transforms, with the
node's markers' label and workpiece), plots of the ram, the shaft speeds and the input
torque, and the stroke-pair diagnostics. The camera looks straight down on the mechanism's
plane with an orthographic view whose height is ``distance`` (how Foxglove's orthographic
camera is defined): centred on the machine's drawn extent and sized so that it fills the panel
at the layout's proportions.
The shipped ``config/foxglove_layout.json`` is this module's output for the default geometry
(a test keeps the two equal).
"""

import json
from typing import Any, Dict, NamedTuple

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics.linkage import linkage_sizes
from qrm_ros.core.common.names import (absolute_topic, DIAGNOSTICS_TOPIC, JOINT_NAMES,
                                       JOINT_STATES_TOPIC, LINKAGE_MARKERS_TOPIC, MACHINE_NAME,
                                       ROBOT_DESCRIPTION_TOPIC, STROKE_PAIR_STATUS)
from qrm_ros.recording.urdf_model import BASE_LINK, urdf_joints

__all__ = ['FOXGLOVE_LAYOUT_FILE_NAME', 'MARKERS_THE_URDF_DRAWS', 'PANEL_ASPECT', 'ViewBounds',
           'foxglove_layout', 'foxglove_layout_text', 'machine_view_bounds']

FOXGLOVE_LAYOUT_FILE_NAME = 'foxglove_layout.json'
# The 3D panel's share of the window's height (it spans the width), and the least width over
# height it is framed for: about 3 in a 1600 x 1000 window with the app's side bar open, 2.6
# leaves room for a narrower one.
SCENE_HEIGHT_SHARE = 0.48
PANEL_ASPECT = 2.6
MARGIN = 1.08  # the view is this much larger than the machine's extent
# The markers' label: its text height, as a share of the ram height (linkage_markers).
LABEL_HEIGHT_SHARE = 0.08
# The node's marker namespaces that draw what the URDF draws: hidden, as the markers come
# less often than the transforms and would show a second, lagging machine. The label (offset,
# TR, SR) and the workpiece stay; a user can show the others in the panel's settings.
MARKERS_THE_URDF_DRAWS = ('frame', 'flywheel', 'coupling_slot', 'links', 'ram', 'pins',
                          'pivots')


class ViewBounds(NamedTuple):
    """The extent (m) of everything drawn, in the ``shaper_base`` plane, over every pose."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float


def machine_view_bounds(geometry: Geometry) -> ViewBounds:
    """
    Return the extent the 3D panel must show.

    The ram at both ends of its stroke, the frame, the lever pivot and flywheel, the tool and
    workpiece below the ram line, the markers' label above it.
    """
    sizes = linkage_sizes(geometry)
    # the ram guide's half length, and the tool's half width beyond the ram's front end
    reach = 0.5 * (float(geometry.ram_stroke) + sizes.ram_length) + 0.5 * sizes.bar_width
    label_height = LABEL_HEIGHT_SHARE * geometry.ram_height
    top = sizes.ram_line_height + sizes.ram_thickness + 2.5 * label_height
    bottom = min(-geometry.pivot_distance - 2.0 * sizes.pin_radius, -sizes.flywheel_radius,
                 sizes.ram_line_height - sizes.tool_drop - sizes.ram_thickness)
    return ViewBounds(-reach, reach, bottom, top)


def _camera(geometry: Geometry) -> Dict[str, Any]:
    bounds = machine_view_bounds(geometry)
    width, height = bounds.x_max - bounds.x_min, bounds.y_max - bounds.y_min
    centre = (0.5 * (bounds.x_min + bounds.x_max), 0.5 * (bounds.y_min + bounds.y_max), 0.0)
    return {
        'perspective': False, 'distance': round(MARGIN * max(height, width / PANEL_ASPECT), 6),
        'phi': 0, 'thetaOffset': 0,
        'targetOffset': [round(value, 6) for value in centre], 'target': [0, 0, 0],
        'targetOrientation': [0, 0, 0, 1], 'fovy': 45, 'near': 0.001, 'far': 100,
    }


def _titled(title: str, config: Dict[str, Any]) -> Dict[str, Any]:
    # Foxglove reads the first key, Lichtblick (its open-source fork) the second.
    return {'foxglovePanelTitle': title, 'lichtblickPanelTitle': title, **config}


def _plot(title: str, paths) -> Dict[str, Any]:
    joint_states = absolute_topic(JOINT_STATES_TOPIC)
    return _titled(title, {
        'paths': [{'value': f'{joint_states}.{field}[{JOINT_NAMES.index(joint)}]',
                   'label': label, 'enabled': True, 'timestampMethod': 'headerStamp'}
                  for field, joint, label in paths],
        'showXAxisLabels': True, 'showYAxisLabels': True, 'showLegend': True,
        'legendDisplay': 'floating', 'showPlotValuesInLegend': True, 'isSynced': True,
        'xAxisVal': 'timestamp', 'sidebarDimension': 240})


def _scene(geometry: Geometry) -> Dict[str, Any]:
    links = [BASE_LINK] + [joint.child for joint in urdf_joints(geometry).values()]
    return _titled('Machine (URDF and markers)', {
        'cameraState': _camera(geometry),
        'followMode': 'follow-pose', 'followTf': BASE_LINK,
        'scene': {'enableStats': False, 'backgroundColor': '#303030',
                  'transforms': {'showLabel': False, 'enablePreloading': True}},
        # No axes: each link's frame hidden (they would hide the small parts).
        'transforms': {f'frame:{link}': {'visible': False} for link in links},
        'layers': {},
        'topics': {absolute_topic(LINKAGE_MARKERS_TOPIC): {
                       'visible': True,
                       'namespaces': {name: {'visible': False}
                                      for name in MARKERS_THE_URDF_DRAWS}},
                   ROBOT_DESCRIPTION_TOPIC: {'visible': True}},
        'imageMode': {}})


def foxglove_layout(geometry: Geometry) -> Dict[str, Any]:
    """Return the layout (JSON-ready) for this geometry."""
    diagnostics = absolute_topic(DIAGNOSTICS_TOPIC)
    return {
        'configById': {
            '3D!linkage': _scene(geometry),
            'Plot!ram': _plot('Ram', [('position', 'ram_joint', 'ram position [m]'),
                                      ('velocity', 'ram_joint', 'ram velocity [m/s]')]),
            'Plot!speeds': _plot('Shaft speeds', [
                ('velocity', 'flywheel_joint', 'flywheel speed [rad/s]'),
                ('velocity', 'input_shaft_joint', 'input speed [rad/s]')]),
            'Plot!torque': _plot('Input torque (with dynamics)', [
                ('effort', 'input_shaft_joint', 'input torque [N m]')]),
            'DiagnosticSummary!summary': _titled('Diagnostics', {
                'minLevel': 0, 'pinnedIds': [], 'hardwareIdFilter': '',
                'topicToRender': diagnostics, 'sortByLevel': True}),
            'DiagnosticStatusPanel!pair': _titled('Stroke pair: measured and theory', {
                'topicToRender': diagnostics, 'selectedHardwareId': MACHINE_NAME,
                'selectedName': STROKE_PAIR_STATUS, 'collapsedSections': []}),
        },
        'globalVariables': {}, 'userNodes': {}, 'linkedGlobalVariables': [],
        'playbackConfig': {'speed': 1},
        # The machine across the top (it is wider than tall), the plots and the diagnostics
        # side by side below.
        'layout': {
            'direction': 'column', 'splitPercentage': round(100 * SCENE_HEIGHT_SHARE, 3),
            'first': '3D!linkage',
            'second': {
                'direction': 'row', 'splitPercentage': 50,
                'first': {'direction': 'column', 'splitPercentage': 33.3, 'first': 'Plot!ram',
                          'second': {'direction': 'column', 'splitPercentage': 50,
                                     'first': 'Plot!speeds', 'second': 'Plot!torque'}},
                'second': {'direction': 'column', 'splitPercentage': 70,
                           'first': 'DiagnosticStatusPanel!pair',
                           'second': 'DiagnosticSummary!summary'}},
        },
    }


def foxglove_layout_text(geometry: Geometry) -> str:
    """Return the layout as the JSON text shipped in ``config/``."""
    return json.dumps(foxglove_layout(geometry), indent=2) + '\n'
