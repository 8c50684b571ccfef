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
``qrm_design``: the design table of the mechanism, and its subcommands.

``qrm_design`` prints what each coupling offset does to the ram's strokes and what the drive
must give per stroke pair (qrm_ros.analysis.design_table); ``qrm_design gearbox`` plans the
gear steps (qrm_ros.core.design.gearbox), ``qrm_design flywheel`` sizes the input side's inertia
for a speed fluctuation (qrm_ros.core.design.flywheel_design). A further subcommand is one line in
SUBCOMMANDS. Exit status: 0 printed; 2 bad options (one line on stderr says why).
"""

import argparse
import json
import math
import sys
from typing import Any, Callable, Dict, Optional, Sequence

import numpy as np

from qrm_ros.analysis.design_table import (DEFAULT_OFFSETS_MM, design_table_data, flywheel_data,
                                           format_design_table, format_flywheel,
                                           format_gearbox_plan)
from qrm_ros.analysis.stroke_table import format_stroke_table, stroke_table_data
from qrm_ros.cli.arguments import (add_drive_arguments, add_geometry_arguments,
                                   drive_from_arguments, geometry_from_arguments,
                                   input_speed_problem, motor_problem)
from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK
from qrm_ros.core.design import gearbox
from qrm_ros.core import kinematics as kin


def _subcommand_parser(name: str, description: str) -> argparse.ArgumentParser:
    """Return the parser of ``qrm_design NAME``."""
    return argparse.ArgumentParser(prog=f'qrm_design {name}', description=description)


def _print_answer(prog: str, compute: Callable[[], Dict[str, Any]],
                  formatter: Callable[[Dict[str, Any]], str], as_json: bool) -> int:
    """Print what COMPUTE returns (JSON or text), or the reason it refused; return the status.

    One rule for every table of the command: a refusal of the options is one line on stderr
    and exit 2 (DynamicsError is a KinematicsError).
    """
    try:
        data = compute()
    except kin.KinematicsError as error:
        print(f'{prog}: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    print(json.dumps(data, indent=2) if as_json else formatter(data))
    return EXIT_OK


def gearbox_main(argv: Sequence[str]) -> int:
    """Run ``qrm_design gearbox``; return the exit status."""
    parser = _subcommand_parser(
        'gearbox',
        'Plan the fewest gear steps (input speeds in geometric progression) that, '
        'with the coupling offset, reach every cutting speed in a range exactly; '
        'beside it the conventional gearbox without offset. Forward running.')
    add_geometry_arguments(parser)
    parser.add_argument('--min-cutting-speed', type=float, required=True,
                        help='lowest wanted cutting speed [m/s]')
    parser.add_argument('--max-cutting-speed', type=float, required=True,
                        help='highest wanted cutting speed [m/s]')
    parser.add_argument('--max-offset', type=float, default=None,
                        help='largest |offset| allowed [m] (default: the node\'s limit, '
                             f'{kin.SAFE_OFFSET_FRACTION:g} x coupling radius)')
    parser.add_argument('--min-time-ratio', type=float, default=gearbox.DEFAULT_MIN_TIME_RATIO,
                        help='smallest time ratio allowed, so the return stays quick [-] '
                             '(default: %(default)s)')
    parser.add_argument('--definition', choices=gearbox.DEFINITIONS, default='mean',
                        help='cutting speed: "mean" = stroke / cutting time, as shop tables '
                             'give (default); "peak" = largest ram speed during the cut')
    parser.add_argument('--progression-ratio', type=float, default=1.41,
                        choices=gearbox.STANDARD_PROGRESSION_RATIOS,
                        help='the conventional gearbox drawn in the figure [-] (the table and '
                             'JSON list all standard ratios; default: %(default)s)')
    parser.add_argument('--json', action='store_true',
                        help='print the plan as JSON (SI units) instead of a table')
    parser.add_argument('--figure', metavar='PATH', default=None,
                        help='also write the speed ladder figure (PNG, PDF or SVG) to PATH')
    args = parser.parse_args(argv)
    try:
        geometry = geometry_from_arguments(args)
        plan = gearbox.plan_gearbox(geometry, args.min_cutting_speed, args.max_cutting_speed,
                                    args.definition, args.max_offset, args.min_time_ratio)
    except (kin.KinematicsError, ValueError) as error:
        print(f'qrm_design gearbox: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.figure:
        # matplotlib only when a figure is asked for
        from qrm_ros.analysis import gearbox_figure
        try:
            gearbox_figure.write_speed_ladder(plan, args.figure, args.progression_ratio)
        except ValueError as error:  # a format matplotlib does not write
            print(f'qrm_design gearbox: {error}', file=sys.stderr)
            return EXIT_BAD_INPUT
        except OSError as error:
            print(f'qrm_design gearbox: cannot write {args.figure}: '
                  f'{error.strerror or error}', file=sys.stderr)
            return EXIT_FAILURE
    if args.json:
        print(json.dumps(gearbox.plan_as_dict(plan, geometry), indent=2))
    else:
        print(format_gearbox_plan(plan))
    return EXIT_OK


def flywheel_main(argv: Sequence[str]) -> int:
    """Run ``qrm_design flywheel``; return the exit status."""
    parser = _subcommand_parser(
        'flywheel',
        'Size the input side\'s total inertia (input_inertia, J1) for a wanted '
        'coefficient of speed fluctuation Cs under the motor drive, at one offset and '
        'input speed; beside it the energy method\'s estimate, the Cs of the answer '
        'simulated again and the flywheel_inertia (J2, on the crank shaft) that would '
        'do the same with J1 kept. Takes seconds to a minute (simulations).')
    parser.add_argument('--fluctuation', type=float, required=True,
                        help='wanted Cs = (max - min) / mean input speed [-]')
    parser.add_argument('--offset', type=float, default=0.0,
                        help='coupling offset [m] (default: %(default)s)')
    parser.add_argument('--input-speed', type=float, default=2 * math.pi,
                        help='input speed, the motor\'s speed reference [rad/s] (default: 2 pi)')
    add_geometry_arguments(parser)
    add_drive_arguments(parser)
    parser.add_argument('--json', action='store_true',
                        help='print the sizing as JSON (SI units) instead of text')
    args = parser.parse_args(argv)

    def sizing() -> Dict[str, Any]:
        geometry = geometry_from_arguments(args)
        mass, loads, motor = drive_from_arguments(args)
        return flywheel_data(geometry, mass, loads, motor, args.offset, args.input_speed,
                             args.fluctuation)
    return _print_answer('qrm_design flywheel', sizing, format_flywheel, args.json)


def stroke_main(argv: Sequence[str]) -> int:
    """Run ``qrm_design stroke``; return the exit status."""
    parser = _subcommand_parser(
        'stroke',
        'Print, for a range of ram strokes, the time ratio with no offset (a short stroke '
        'loses its quick return) and the offset that restores a wanted time ratio, with the '
        'flywheel speed swing that offset costs. Forward running.')
    parser.add_argument('--time-ratio', type=float, default=None,
                        help='wanted time ratio [-] (default: the time ratio at offset 0 of '
                             'the stroke of --crank-radius)')
    parser.add_argument('--strokes-mm', type=float, nargs='+', default=None,
                        help='ram strokes to tabulate [mm] (default: 40 to 300 in 20 mm steps)')
    add_geometry_arguments(parser)
    parser.add_argument('--json', action='store_true',
                        help='print the table as JSON (SI units) instead of text')
    args = parser.parse_args(argv)

    def table() -> Dict[str, Any]:
        geometry = geometry_from_arguments(args)
        target = (float(kin.time_ratio(geometry, 0.0)) if args.time_ratio is None
                  else args.time_ratio)
        strokes = (np.asarray(args.strokes_mm) if args.strokes_mm
                   else np.arange(40.0, 300.0 + 1e-9, 20.0)) / 1e3
        return stroke_table_data(geometry, strokes, target)
    return _print_answer('qrm_design stroke', table, format_stroke_table, args.json)


# Subcommands of qrm_design: name -> main(argv) returning the exit code.
SUBCOMMANDS: Dict[str, Callable[[Sequence[str]], int]] = {
    'gearbox': gearbox_main,
    'flywheel': flywheel_main,
    'stroke': stroke_main,
}


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run qrm_design (the table, or a subcommand); return the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in SUBCOMMANDS:
        return SUBCOMMANDS[argv[0]](argv[1:])
    parser = argparse.ArgumentParser(
        prog='qrm_design',
        description='Print TR and SR over a range of coupling offsets, and what the drive must '
                    'give per stroke pair (peak and RMS input torque, mean power, energy, peak '
                    'offset force) under the ideal speed drive.',
        epilog='subcommands: ' + ', '.join(f'qrm_design {name} --help' for name in SUBCOMMANDS))
    add_geometry_arguments(parser)
    parser.add_argument('--input-speed', type=float, default=2 * math.pi,
                        help='input shaft speed [rad/s] (default: 2 pi)')
    parser.add_argument('--offsets-mm', type=float, nargs='+', default=None,
                        help='offsets to tabulate [mm] (default: -20 to 20 in 2.5 mm steps)')
    parser.add_argument('--speed-fluctuation', action='store_true',
                        help='add the column Cs under the motor drive: a simulation per offset, '
                             'about 0.35 s each (off by default)')
    parser.add_argument('--json', action='store_true',
                        help='print the table as JSON (SI units) instead of text')
    add_drive_arguments(parser)
    args = parser.parse_args(argv)

    def table() -> Dict[str, Any]:
        geometry = geometry_from_arguments(args)
        mass, loads, motor = drive_from_arguments(args)
        problem = input_speed_problem('--input-speed', args.input_speed) or (
            motor_problem(mass, motor) if args.speed_fluctuation else None)
        if problem:
            raise kin.KinematicsError(problem)
        offsets = (np.asarray(args.offsets_mm) if args.offsets_mm else DEFAULT_OFFSETS_MM) / 1e3
        return design_table_data(geometry, offsets, args.input_speed, mass, loads,
                                 motor if args.speed_fluctuation else None)
    return _print_answer('qrm_design', table, format_design_table, args.json)


if __name__ == '__main__':
    sys.exit(main())
