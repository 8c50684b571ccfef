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
Design table of the mechanism: what each coupling offset does to the ram's strokes.

Printed by ``qrm_design`` (and at the end of the main job), straight from the kinematics core,
so a designer can pick an offset before running anything. ``qrm_design gearbox`` plans the
gear steps (see qrm_ros.gearbox); further subcommands are one line in SUBCOMMANDS.
"""

import argparse
import json
import math
import sys

import numpy as np

from qrm_ros import gearbox
from qrm_ros import kinematics as kin

DEFAULT_OFFSETS_MM = np.arange(-20.0, 20.0 + 1e-9, 2.5)


def design_rows(geometry, offsets, input_speed):
    """One dict per offset with every figure the table prints, in SI units."""
    theory = kin.steady_theory(geometry, offsets, input_speed)
    return [dict(offset=float(offsets[i]),
                 offset_over_pivot_distance=float(offsets[i] / geometry.pivot_distance),
                 **{name: float(values[i]) for name, values in theory._asdict().items()})
            for i in range(len(offsets))]


def format_design_table(geometry, offsets, input_speed):
    lines = [
        'Modified quick-return mechanism: design table (exact closed form)',
        f'  coupling radius r1 = {geometry.coupling_radius * 1e3:g} mm, crank radius r = '
        f'{geometry.crank_radius * 1e3:g} mm, pivot distance h = '
        f'{geometry.pivot_distance * 1e3:g} mm, ram height H = {geometry.ram_height * 1e3:g} mm,'
        f' crank phase = {geometry.crank_phase:g} rad',
        f'  ram stroke = {geometry.ram_stroke * 1e3:.4f} mm; input speed = {input_speed:g} rad/s'
        f' ({input_speed * 30 / math.pi:.4g} rpm); cutting stroke moves the ram toward -x',
        '',
        '  offset   offset/h        TR        SR   peak SR   t_cut   t_ret  v_cut,max  '
        'v_ret,max',
        '    [mm]        [-]       [-]       [-]       [-]     [s]     [s]      [m/s]      '
        '[m/s]',
    ]
    for row in design_rows(geometry, offsets, input_speed):
        lines.append(
            f'{row["offset"] * 1e3:8.2f} {row["offset_over_pivot_distance"]:+10.5f} '
            f'{row["time_ratio"]:9.5f} {row["speed_ratio"]:9.5f} {row["peak_speed_ratio"]:9.5f} '
            f'{row["cutting_time"]:7.4f} {row["return_time"]:7.4f} '
            f'{row["peak_cutting_speed"]:10.5f} {row["peak_return_speed"]:10.5f}')
    lines.append('')
    unity_sr = kin.offset_for_speed_ratio(geometry, 1.0)
    lines.append(f'  SR = 1 (equal mid-stroke cutting and return speeds) at offset '
                 f'{unity_sr * 1e3:.6f} mm (eq. 26: -r r1 / h)')
    for target in (1.0, 2.0, 3.0):
        try:
            offset = kin.offset_for_time_ratio(geometry, target)
            lines.append(f'  TR = {target:g} at offset {offset * 1e3:.6f} mm')
        except kin.KinematicsError as error:
            lines.append(f'  TR = {target:g}: {error}')
    lines.append(f'  offsets accepted by the node: |offset| <= {geometry.max_safe_offset * 1e3:g}'
                 f' mm ({kin.SAFE_OFFSET_FRACTION:g} x r1)')
    return '\n'.join(lines)


def add_geometry_arguments(parser, defaults=True):
    """Add --coupling-radius etc.; defaults are the paper's geometry, or None if not wanted."""
    paper = kin.Geometry.paper()
    for name, unit in (('coupling_radius', 'm'), ('crank_radius', 'm'), ('pivot_distance', 'm'),
                       ('ram_height', 'm'), ('crank_phase', 'rad')):
        default = getattr(paper, name) if defaults else None
        shown = ' (default: %(default)s)' if defaults else ''
        parser.add_argument('--' + name.replace('_', '-'), type=float, default=default,
                            help=f'{name.replace("_", " ")} [{unit}]{shown}')


def geometry_from_arguments(args):
    return kin.Geometry(args.coupling_radius, args.crank_radius, args.pivot_distance,
                        args.ram_height, args.crank_phase)


def format_gearbox_plan(plan):
    """Format the plan: steps with the offset, then the conventional gearboxes."""
    offsets = plan.offsets
    lines = [
        f'Gearbox for {plan.definition} cutting speeds {plan.min_cutting_speed:g} to '
        f'{plan.max_cutting_speed:g} m/s ({plan.min_cutting_speed * 60:g} to '
        f'{plan.max_cutting_speed * 60:g} m/min), forward running',
        f'  usable offsets: {offsets.offset_min * 1e3:.4f} to {offsets.offset_max * 1e3:.4f} mm'
        f' (|offset| <= {plan.max_offset * 1e3:g} mm, TR >= {plan.min_time_ratio:g}); cutting '
        f'speed per input speed {offsets.slowest_per_input_speed:.6g} to '
        f'{offsets.fastest_per_input_speed:.6g} m/rad (band ratio {plan.band_ratio:.6g})',
        f'  with the offset: {len(plan.steps)} steps, progression ratio '
        f'{plan.progression_ratio:.6g}',
        '',
        '  step  input speed        cutting speed [m/s]      offset at min/max [mm]',
        '          [rad/s]   [rpm]      min         max          min        max',
    ]
    for number, step in enumerate(plan.steps, 1):
        lines.append(f'{number:6d} {step.input_speed:9.5f} {step.input_speed * 30 / math.pi:7.3f}'
                     f' {step.cutting_speed_min:11.6f} {step.cutting_speed_max:11.6f} '
                     f'{step.offset_at_min * 1e3:11.6f} {step.offset_at_max * 1e3:10.6f}')
    lines += ['', '  without the offset (offset = 0), geometric steps, each wanted speed cut at '
              'the fastest step not above it:',
              '  progression ratio   max shortfall   steps']
    for box in plan.conventional:
        lines.append(f'{box.progression_ratio:19g} {box.max_shortfall * 100:13.1f} % '
                     f'{box.step_count:7d}')
    return '\n'.join(lines)


def gearbox_main(argv):
    parser = argparse.ArgumentParser(
        prog='qrm_design gearbox',
        description='Plan the fewest gear steps (input speeds in geometric progression) that, '
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
        if args.figure:
            from qrm_ros import gearbox_figure
            gearbox_figure.write_speed_ladder(plan, args.figure, args.progression_ratio)
    except (kin.KinematicsError, OSError, ValueError) as error:
        print(f'qrm_design gearbox: {error}', file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(gearbox.plan_as_dict(plan, geometry), indent=2))
    else:
        print(format_gearbox_plan(plan))
    return 0


# Subcommands of qrm_design: name -> main(argv) returning the exit code.
SUBCOMMANDS = {
    'gearbox': gearbox_main,
}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in SUBCOMMANDS:
        return SUBCOMMANDS[argv[0]](argv[1:])
    parser = argparse.ArgumentParser(
        prog='qrm_design', description='Print TR and SR over a range of coupling offsets.',
        epilog='subcommands: ' + ', '.join(f'qrm_design {name} --help' for name in SUBCOMMANDS))
    add_geometry_arguments(parser)
    parser.add_argument('--input-speed', type=float, default=2 * math.pi,
                        help='input shaft speed [rad/s] (default: 2 pi)')
    parser.add_argument('--offsets-mm', type=float, nargs='+', default=None,
                        help='offsets to tabulate [mm] (default: -20 to 20 in 2.5 mm steps)')
    args = parser.parse_args(argv)
    try:
        geometry = geometry_from_arguments(args)
        offsets = (np.asarray(args.offsets_mm) if args.offsets_mm else DEFAULT_OFFSETS_MM) / 1e3
        print(format_design_table(geometry, offsets, args.input_speed))
    except kin.KinematicsError as error:
        print(f'qrm_design: {error}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
