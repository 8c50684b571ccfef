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
What drove the machine in a recorded run: masses, loads and drive, from the parameters.

The recorder stores the node's parameter values in the file's metadata; the changes made
while it ran come as /parameter_events, stamped with the node's clock. Together they give
the theory of the efforts for every part of the run, or say why there is none.
"""

import json
import math
from typing import Any, Dict, List, NamedTuple, Optional, Tuple

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import (MOTOR_DRIVE, PARAMETER_EVENTS_TOPIC, PARAMETERS_METADATA,
                                       SIM_NODE_NAME, SPEED_DRIVE)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.recording.bag_reader import Run
from qrm_ros.recording.typestore import jazzy_typestore

PARAMETER_STRING = 4  # rcl_interfaces/msg/ParameterType.PARAMETER_STRING
# The node's parameters that make the drive (Drive): its masses, loads and motor, and which.
DRIVE_PARAMETERS = frozenset(
    ['drive', *(name for kind in dyn.PARAMETER_PREFIXES for name in dyn.parameter_names(kind))])


class Drive(NamedTuple):
    """The node's mass properties, loads and drive as recorded: the theory of the efforts."""

    mass: dyn.MassProperties
    loads: dyn.Loads
    motor: Optional[dyn.MotorDrive]  # None: the ideal speed drive


class DriveSpan(NamedTuple):
    """The mass properties, loads and drive in force from start_time (s, samples' clock) on."""

    start_time: float
    drive: Optional[Drive]
    problem: Optional[str]  # why drive is None
    unreadable: bool = False  # a parameter event could not be read: the data lacks the drive


def drive_from_metadata(stored: Optional[Dict[str, str]],
                        geometry: kin.Geometry) -> Tuple[Optional[Drive], Optional[str]]:
    """Read the recorded mass properties, loads and drive; or None and why no theory."""
    values, problem = stored_parameters(stored)
    if values is None:
        return None, problem
    return drive_of_values(values, geometry)


def stored_parameters(stored: Optional[Dict[str, str]]
                      ) -> Tuple[Optional[Dict[str, Any]], Optional[str]]:
    """Return the node's recorded parameter values (JSON in the metadata), or why none."""
    if stored is None:
        return None, f'the file has no {PARAMETERS_METADATA} metadata'
    try:
        return {name: json.loads(text) for name, text in stored.items()}, None
    except ValueError:
        return None, f'the {PARAMETERS_METADATA} metadata is not JSON'


def drive_of_values(values: Dict[str, Any],
                    geometry: kin.Geometry) -> Tuple[Optional[Drive], Optional[str]]:
    """Make the mass properties, loads and drive of parameter values; or None and why not."""
    drive = values.get('drive', SPEED_DRIVE)
    wanted = {kind: dict(zip(kind.field_names(), dyn.parameter_names(kind)))
              for kind in dyn.PARAMETER_PREFIXES}
    if drive not in (SPEED_DRIVE, MOTOR_DRIVE):
        return None, f'the recorded drive {drive!r} is unknown (expected speed or motor)'
    kinds = [dyn.MassProperties, dyn.Loads] + ([dyn.MotorDrive] if drive == MOTOR_DRIVE
                                               else [])
    missing = [key for kind in kinds for key in wanted[kind].values() if key not in values]
    if missing:
        return None, (f'the {PARAMETERS_METADATA} metadata lacks {", ".join(missing)} '
                      '(recorded before the node had them)')
    try:
        made = [kind(**{name: values[key] for name, key in wanted[kind].items()})
                for kind in kinds]
        made[1].check_against(geometry.ram_stroke)
    except kin.KinematicsError as error:  # DynamicsError is one
        return None, f'the recorded mass properties or loads are refused: {error}'
    return Drive(made[0], made[1], made[2] if drive == MOTOR_DRIVE else None), None


def drive_changes(run: Run, stored: Optional[Dict[str, str]],
                  geometry: kin.Geometry, origin_ns: int) -> Tuple[DriveSpan, ...]:
    """
    Return the drives that the node's parameter events put in force mid-run.

    The events are stamped with the node's clock, as the joint states are, so each change
    falls between the two samples it came between. Only the chunks that hold events are
    read again (the file's message indexes say which), so this costs little.
    """
    values, _ = stored_parameters(stored)
    if values is None or PARAMETER_EVENTS_TOPIC not in run.topics():
        return ()
    spans: List[DriveSpan] = []
    store = jazzy_typestore()
    for message in run.messages([PARAMETER_EVENTS_TOPIC], on_loss=lambda loss: None):
        try:
            event = store.deserialize_cdr(message.data, message.schema_name)
            changed = [(p.name, parameter_value(p.value)) for p in event.changed_parameters
                       if p.name in DRIVE_PARAMETERS]
            node = event.node.rsplit('/', 1)[-1]
            stamp = event.stamp.sec * NANOSECONDS_PER_SECOND + event.stamp.nanosec
        except Exception as error:  # noqa: B902 any undecodable bytes
            # Whose change it was, and when, is unknown: from the last change known on, so
            # is the drive (a later event says only what it changes).
            since = spans[-1].start_time if spans else -math.inf
            when = f'{since:.6f} s' if spans else 'the start'
            spans.append(DriveSpan(since, None, (
                f'a {PARAMETER_EVENTS_TOPIC} message (log time {message.log_time} ns) could '
                f'not be read ({error}): the masses, loads and drive from {when} on are '
                'unknown'), True))
            return tuple(spans)
        if node != SIM_NODE_NAME or not changed:
            continue
        values.update(changed)
        drive, problem = drive_of_values(values, geometry)
        spans.append(DriveSpan((stamp - origin_ns) / NANOSECONDS_PER_SECOND, drive, problem))
    return tuple(spans)


def parameter_value(value: Any) -> Any:
    """Return a ParameterValue's scalar (the drive's parameters are doubles and a string)."""
    return value.string_value if value.type == PARAMETER_STRING else value.double_value


def drive_values(drive: Optional[Drive]) -> Dict[str, Any]:
    """Return a drive as the node's parameter names -> values ({}: no drive known)."""
    if drive is None:
        return {}
    values: Dict[str, Any] = {'drive': SPEED_DRIVE if drive.motor is None else MOTOR_DRIVE}
    for part in (drive.mass, drive.loads, drive.motor):
        if part is not None:
            values.update(zip(dyn.parameter_names(type(part)), part.as_dict().values()))
    return values


def drive_differences(before: Optional[Drive], after: Optional[Drive]) -> List[str]:
    """Say what changed between two drives, by parameter name ('cutting_force 400 -> 800')."""
    old, new = drive_values(before), drive_values(after)
    return [f'{name} {old.get(name, "?")} -> {new.get(name, "?")}'
            for name in sorted(set(old) | set(new)) if old.get(name) != new.get(name)]
