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
Design tables of the mechanism: what each coupling offset does to the ram's strokes.

Printed by ``qrm_design`` (qrm_ros.cli.qrm_design), straight from the kinematics and
dynamics cores, so a designer can pick an offset before running anything: the stroke
figures, then what the drive must give per stroke pair (and, asked for, the speed
fluctuation under the motor); the gearbox plan (qrm_ros.core.design.gearbox) and the flywheel
sizing (qrm_ros.core.design.flywheel_design) as text. Each table is a JSON-ready dict in SI units
first, then its text.
"""

import math
from typing import Any, Dict, Iterable, List, Optional

import numpy as np
from numpy.typing import ArrayLike

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.design import flywheel_design
from qrm_ros.core import kinematics as kin
from qrm_ros.core.design.gearbox import GearboxPlan
from qrm_ros.core.dynamics.speed_drive import pair_efforts
from qrm_ros.core.motor.steady_running import speed_fluctuation

DEFAULT_OFFSETS_MM = np.arange(-20.0, 20.0 + 1e-9, 2.5)


def design_rows(geometry: kin.Geometry, offsets: np.ndarray,
                input_speed: float) -> List[Dict[str, float]]:
    """One dict per offset with every figure the table prints, in SI units."""
    theory = kin.steady_theory(geometry, offsets, input_speed)
    return [dict(offset=float(offsets[i]),
                 offset_over_pivot_distance=float(offsets[i] / geometry.pivot_distance),
                 **{name: float(values[i]) for name, values in theory._asdict().items()})
            for i in range(len(offsets))]


def drive_rows(geometry: kin.Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
               motor: Optional[dyn.MotorDrive], offsets: Iterable[float],
               input_speed: float) -> List[Dict[str, Any]]:
    """
    One dict per offset: the speed drive's ``PairEfforts``, and Cs under motor if not None.

    Cs is a simulation per offset; where it fails (a stall, no steady state) the row's
    speed_fluctuation is None and speed_fluctuation_problem says why.
    """
    rows = []
    for offset in offsets:
        figures = pair_efforts(geometry, mass, loads, float(offset), input_speed)
        row = dict(figures._asdict())
        if motor is not None:
            try:
                row['speed_fluctuation'] = speed_fluctuation(
                    geometry, mass, loads, motor, float(offset), input_speed).fluctuation
            except dyn.DynamicsError as error:
                row['speed_fluctuation'] = None
                row['speed_fluctuation_problem'] = str(error)
        rows.append(row)
    return rows


def design_table_data(geometry: kin.Geometry, offsets: ArrayLike, input_speed: float,
                      mass: dyn.MassProperties, loads: dyn.Loads,
                      motor: Optional[dyn.MotorDrive] = None) -> Dict[str, Any]:
    """Everything the design table prints, as a JSON-ready dict in SI units."""
    offsets = np.asarray(offsets, dtype=float)
    loads.check_against(geometry.ram_stroke)
    if motor is not None and not input_speed > 0.0:
        raise kin.KinematicsError(f'input_speed must be > 0 rad/s for the speed fluctuation '
                                  f'(the motor runs forward), got {input_speed!r}')
    rows = [{**kinematic, **drive} for kinematic, drive in zip(
        design_rows(geometry, offsets, input_speed),
        drive_rows(geometry, mass, loads, motor, offsets, input_speed))]
    time_ratio_offsets: List[Dict[str, Any]] = []
    for target in (1.0, 2.0, 3.0):
        try:
            time_ratio_offsets.append({'time_ratio': target,
                                       'offset': kin.offset_for_time_ratio(geometry, target)})
        except kin.KinematicsError as error:
            time_ratio_offsets.append({'time_ratio': target, 'offset': None,
                                       'problem': str(error)})
    return {
        'geometry': geometry_dict(geometry), 'input_speed': float(input_speed),
        'ram_stroke': geometry.ram_stroke,
        'mass_properties': mass.as_dict(), 'loads': loads.as_dict(),
        'motor': None if motor is None else motor.as_dict(),
        'rows': rows,
        'offset_for_unity_speed_ratio': kin.offset_for_speed_ratio(geometry, 1.0),
        'offsets_for_time_ratio': time_ratio_offsets,
        'max_safe_offset': geometry.max_safe_offset,
    }


def geometry_dict(geometry: kin.Geometry) -> Dict[str, float]:
    """Return the geometry as plain floats (JSON-ready)."""
    return {name: float(value) for name, value in geometry.as_dict().items()}


def describe(title: str, values: Dict[str, float], kind: Any) -> List[str]:
    """Indented 'title: name value unit, ...' of a parameter set's dict, wrapped at 99."""
    units = kind.units()
    items = [f'{name} {value:g} {units[name]}' for name, value in values.items()]
    lines = [f'  {title}: {items[0]}']
    for item in items[1:]:
        if len(lines[-1]) + len(item) + 2 > 99:
            lines[-1] += ','
            lines.append(f'    {item}')
        else:
            lines[-1] += f', {item}'
    return lines


def format_design_table(data: Dict[str, Any]) -> str:
    """Format ``design_table_data``'s dict: the kinematics, then the drive per offset."""
    geometry = kin.Geometry(**data['geometry'])
    input_speed = data['input_speed']
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
    for row in data['rows']:
        lines.append(
            f'{row["offset"] * 1e3:8.2f} {row["offset_over_pivot_distance"]:+10.5f} '
            f'{row["time_ratio"]:9.5f} {row["speed_ratio"]:9.5f} {row["peak_speed_ratio"]:9.5f} '
            f'{row["cutting_time"]:7.4f} {row["return_time"]:7.4f} '
            f'{row["peak_cutting_speed"]:10.5f} {row["peak_return_speed"]:10.5f}')
    lines.append('')
    lines.append(f'  SR = 1 (equal mid-stroke cutting and return speeds) at offset '
                 f'{data["offset_for_unity_speed_ratio"] * 1e3:.6f} mm (eq. 26: -r r1 / h)')
    for entry in data['offsets_for_time_ratio']:
        if entry['offset'] is None:
            lines.append(f'  TR = {entry["time_ratio"]:g}: {entry["problem"]}')
        else:
            lines.append(f'  TR = {entry["time_ratio"]:g} at offset '
                         f'{entry["offset"] * 1e3:.6f} mm')
    lines.append(f'  offsets accepted by the node: |offset| <= {data["max_safe_offset"] * 1e3:g}'
                 f' mm ({kin.SAFE_OFFSET_FRACTION:g} x r1)')
    lines += [''] + format_drive_rows(data)
    return '\n'.join(lines)


def format_drive_rows(data: Dict[str, Any]) -> List[str]:
    """Format the drive's part of the table: efforts per stroke pair and, if asked, Cs."""
    motor = data['motor']
    lines = [
        f'  Drive, per stroke pair at each offset: ideal speed drive (input held at '
        f'{data["input_speed"]:g} rad/s)',
        *describe('mass properties', data['mass_properties'], dyn.MassProperties),
        *describe('loads', data['loads'], dyn.Loads),
        "  mean power = energy per pair / revolution time; the energy is the loads' work (the cut "
        'once over',
        '  the workpiece, friction over twice the stroke): the offset changes the torques, not '
        'the energy',
    ]
    if motor is None:
        lines.append('  Cs (speed fluctuation under the motor drive): add --speed-fluctuation '
                     '(a simulation per')
        lines.append('  offset, about 0.35 s each)')
    else:
        lines.append(f'  Cs = (max - min) / mean input speed, steady, under the motor drive with '
                     f'reference {data["input_speed"]:g} rad/s')
        lines += describe('motor', motor, dyn.MotorDrive)
    lines += ['',
              '  offset  peak tau_in  RMS tau_in  mean power  energy/pair  peak F_offset'
              + ('         Cs' if motor else ''),
              '    [mm]        [N*m]       [N*m]         [W]          [J]            [N]'
              + ('        [-]' if motor else '')]
    problems = []
    for row in data['rows']:
        line = (f'{row["offset"] * 1e3:8.2f} {row["peak_input_torque"]:12.4f} '
                f'{row["rms_input_torque"]:11.4f} {row["mean_input_power"]:11.4f} '
                f'{row["energy_per_pair"]:12.4f} {row["peak_offset_force"]:14.3f}')
        if motor is not None:
            if row['speed_fluctuation'] is None:
                line += f'{"--":>11}'
                problems.append(f'  offset {row["offset"] * 1e3:g} mm, Cs: '
                                f'{row["speed_fluctuation_problem"]}')
            else:
                line += f' {row["speed_fluctuation"]:10.6f}'
        lines.append(line)
    return lines + problems


def format_gearbox_plan(plan: GearboxPlan) -> str:
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


def flywheel_data(geometry: kin.Geometry, mass: dyn.MassProperties, loads: dyn.Loads,
                  motor: dyn.MotorDrive, offset: float, input_speed: float,
                  fluctuation: float) -> Dict[str, Any]:
    """Size the flywheel; return the sizing and what it was asked with, JSON-ready, SI units."""
    sizing = flywheel_design.size_flywheel(geometry, mass, loads, motor, offset, input_speed,
                                           fluctuation)
    return {'geometry': geometry_dict(geometry),
            'offset': float(offset), 'input_speed': float(input_speed),
            'mass_properties': mass.as_dict(), 'loads': loads.as_dict(),
            'motor': motor.as_dict(), **sizing._asdict()}


def format_flywheel(data: Dict[str, Any]) -> str:
    """Format ``flywheel_data``'s dict: the refined J1, the energy method, the equivalent J2."""
    mass = data['mass_properties']
    input_speed = data['input_speed']
    wanted = data['speed_fluctuation']
    lines = [
        f'Flywheel for a speed fluctuation Cs = {wanted:g} under the motor drive',
        f'  offset {data["offset"] * 1e3:g} mm, input speed {input_speed:g} rad/s '
        f'({input_speed * 30 / math.pi:.4g} rpm)',
        '  Cs = (max - min) / mean input speed over a steady revolution, simulated',
        *describe('motor', data['motor'], dyn.MotorDrive),
        *describe('mass properties', mass, dyn.MassProperties),
        *describe('loads', data['loads'], dyn.Loads),
        '',
        '  input_inertia J1 is the whole input side: motor rotor and gearbox referred to the '
        'input',
        '  shaft, input shaft, coupling, and a flywheel added there.',
        f'  given J1 = {mass["input_inertia"]:.6g} kg*m^2: Cs = '
        f'{data["given_speed_fluctuation"]:.6g}',
        f'  J1 for Cs = {wanted:g}: {data["input_inertia"]:.6g} kg*m^2 (refined by simulation), '
        f'{data["added_input_inertia"]:+.6g} kg*m^2 on the given J1',
        f'    simulated again with it: Cs = {data["simulated_speed_fluctuation"]:.6g}',
        '  energy method (dynamics.md; it ignores the motor\'s own stiffness):',
        f'    total equivalent inertia Delta E / (Cs w^2) = {data["energy_method_inertia"]:.6g} '
        'kg*m^2',
        f'    less the rest of the chain\'s mean share, {data["chain_mean_inertia"]:.6g} kg*m^2: '
        f'J1 = {data["energy_method_input_inertia"]:.6g} kg*m^2',
    ]
    flywheel = data['equivalent_flywheel_inertia']
    ratio = data['flywheel_mean_square_ratio']
    if flywheel is None:
        lines += ['  on the crank shaft instead, J1 kept: none, the flywheel_inertia J2 would be '
                  '< 0',
                  f'    (given J2 + delta J1 / mean (dphi/dtheta)^2, mean = {ratio:.6g})']
    else:
        simulated = f'    simulated with it: Cs = {data["equivalent_speed_fluctuation"]:.6g}'
        lines += [
            f'  or on the crank shaft, J1 kept: flywheel_inertia J2 = {flywheel:.6g} kg*m^2',
            f'    (given J2 + delta J1 / mean (dphi/dtheta)^2, mean = {ratio:.6g})',
        ]
        if data['offset'] == 0.0:
            lines.append(simulated + ' (at offset 0 the same machine)')
        else:
            lines += [simulated + ' (an estimate: with an offset the crank\'s speed swings every',
                      '    revolution, and J2\'s inertia torque with it)']
    return '\n'.join(lines)
