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
Argument helpers the commands share: the geometry and the drive as options.

The options carry the names of the node's parameters (``--coupling-radius``,
``--motor-speed-stiffness``, ...), so a design, a URDF and an analysis are asked for in the
words the node uses.
"""

import argparse
import math
from typing import Any, Dict, Optional, Tuple

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke, Geometry, KinematicsError
from qrm_ros.core.dynamics.physical_ranges import (MAX_INPUT_SPEED, MIN_INPUT_SPEED,
                                                   motor_speed_band_problem,
                                                   motor_time_constant_problem)


def add_geometry_arguments(parser: Any, defaults: bool = True) -> None:
    """
    Add --coupling-radius etc.; defaults are the paper's geometry, or None if not wanted.

    ``parser``: an ArgumentParser or one of its argument groups.
    """
    paper = Geometry.paper()
    for name, unit in (('coupling_radius', 'm'), ('crank_radius', 'm'), ('pivot_distance', 'm'),
                       ('ram_height', 'm'), ('crank_phase', 'rad')):
        default = getattr(paper, name) if defaults else None
        shown = ' (default: %(default)s)' if defaults else ''
        parser.add_argument('--' + name.replace('_', '-'), type=float, default=default,
                            help=f'{name.replace("_", " ")} [{unit}]{shown}')
    if defaults:  # a whole geometry (not overrides of a recorded one)
        parser.add_argument('--stroke-length', type=float, default=None,
                            help='ram stroke [m], instead of --crank-radius: the crank radius '
                                 'that gives it, r = S h / sqrt(4 H^2 + S^2)')


def geometry_from_arguments(args: argparse.Namespace) -> Geometry:
    """
    Return the Geometry of add_geometry_arguments' options (KinematicsError if unusable).

    --stroke-length, where given, sets the crank radius instead (r = S h / sqrt(4 H^2 +
    S^2)); with --crank-radius too it is refused.
    """
    phase = args.crank_phase
    if phase is not None and not -math.pi <= phase <= math.pi:  # as the node's crank_phase
        raise KinematicsError(f'--crank-phase = {phase!r} rad is out of range: allowed '
                              f'[{-math.pi:.6g}, {math.pi:.6g}] rad')
    radius = args.crank_radius
    stroke = getattr(args, 'stroke_length', None)
    if stroke is not None:
        if radius is not None and radius != Geometry.paper().crank_radius:
            raise KinematicsError('give --stroke-length or --crank-radius, not both')
        if not (math.isfinite(stroke) and stroke > 0.0):
            raise KinematicsError(f'--stroke-length {stroke!r} m is out of range: allowed a '
                                  'finite value > 0')
        radius = float(crank_radius_for_stroke(stroke, args.pivot_distance, args.ram_height))
    return Geometry(args.coupling_radius, radius, args.pivot_distance, args.ram_height,
                    args.crank_phase)


# The parameter sets a drive needs, as (kind, option prefix, group title); the options carry
# the node's parameter names (dynamics.PARAMETER_PREFIXES: motor_speed_stiffness, ...).
DRIVE_PARAMETER_SETS = tuple((kind, dyn.PARAMETER_PREFIXES[kind], title) for kind, title in (
    (dyn.MassProperties, 'mass properties'), (dyn.Loads, 'loads on the ram'),
    (dyn.MotorDrive, 'motor')))


def add_drive_arguments(parser: argparse.ArgumentParser) -> None:
    """Add --input-inertia ... --motor-max-torque; defaults: the small shaper's (dynamics)."""
    for kind, prefix, title in DRIVE_PARAMETER_SETS:
        group = parser.add_argument_group(
            f'{title} (defaults: dynamics.{kind.__name__}.small_shaper(), which says where '
            'each comes from)')
        defaults = kind.small_shaper()
        for name, unit in kind.units().items():
            group.add_argument('--' + (prefix + name).replace('_', '-'), dest=prefix + name,
                               type=float, default=getattr(defaults, name),
                               help=f'{name.replace("_", " ")} [{unit}] (default: %(default)s)')


def drive_from_arguments(args: argparse.Namespace) -> Tuple[Any, ...]:
    """Return (MassProperties, Loads, MotorDrive) from add_drive_arguments' options."""
    return tuple(kind(**{name: getattr(args, prefix + name) for name in kind.field_names()})
                 for kind, prefix, _ in DRIVE_PARAMETER_SETS)


def input_speed_problem(option: str, input_speed: float) -> Optional[str]:
    """Say why an input speed option (rad/s, either sign) is out of range, or None."""
    if MIN_INPUT_SPEED <= abs(input_speed) <= MAX_INPUT_SPEED:
        return None
    return (f'{option} (input_speed) = {input_speed!r} rad/s is out of range: allowed '
            f'{MIN_INPUT_SPEED:g} <= |input speed| <= {MAX_INPUT_SPEED:g} rad/s')


def motor_problem(mass: dyn.MassProperties, motor: dyn.MotorDrive) -> Optional[str]:
    """Say why the motor cannot be simulated with these masses (physical_ranges), or None."""
    return (motor_time_constant_problem(mass.input_inertia, mass.flywheel_inertia,
                                        motor.speed_stiffness)
            or motor_speed_band_problem(motor.speed_stiffness, motor.max_torque))


def add_geometry_override_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the geometry options, as a group without defaults, to a command reading a run."""
    geometry_group = parser.add_argument_group(
        'geometry', 'override (or supply, for files without it) the stored geometry')
    add_geometry_arguments(geometry_group, defaults=False)


def geometry_overrides(args: argparse.Namespace) -> Dict[str, Optional[float]]:
    """Return the geometry options as given (None: not given) by add_geometry_arguments."""
    return {name: getattr(args, name) for name in Geometry.field_names()}
