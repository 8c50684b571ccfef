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
Figures of an analysed run, after the source paper's Figs. 10-12.

Theory curves come from the kinematics core for the recording's geometry (their lines carry
gid 'theory' so tests can compare them with the core); measured points come from the run.
Every axis is labelled with its unit so a figure reads without the table.
"""

import dataclasses
import math
import os
from typing import Callable, cast, Dict, List, Optional

from matplotlib.figure import Figure
import numpy as np

from qrm_ros.analysis.measurement import Analysis
from qrm_ros.analysis.plotting import plt
from qrm_ros.analysis.theory import flywheel_speed_swing, input_torque_parts
from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke
from qrm_ros.core.dynamics.speed_drive import pair_efforts

THEORY = 'theory'
THEORY_FAMILY = 'theory-family'
OTHER_CRANK_RADII = (0.01, 0.03, 0.07)  # m, dashed theory curves in the TR figure
CURVE_POINTS = 400


def _offset_axis(geometry):
    limit = geometry.max_safe_offset
    return np.linspace(-limit, limit, CURVE_POINTS)


def _directions(analysis):
    return sorted({math.copysign(1.0, row['input_speed']) for row in analysis.rows
                   if row['input_speed'] != 0.0}, reverse=True) or [1.0]


def _measured(analysis, key):
    rows = [r for r in analysis.rows if r[f'{key}_measured'] is not None]
    x = np.array([r['offset_over_pivot_distance'] for r in rows])
    y = np.array([r[f'{key}_measured'] for r in rows])
    spread = np.array([r[f'{key}_measured_std'] for r in rows])
    return x, y, spread


def _row_strokes(analysis: Analysis, key: str) -> np.ndarray:
    """Crank radius of each measured row (the recording's where it recorded none)."""
    radius = analysis.recording.geometry.crank_radius
    return np.array([r.get('crank_radius', radius) for r in analysis.rows
                     if r[f'{key}_measured'] is not None])


def time_ratio_stroke_figure(analysis: Analysis) -> Figure:
    """TR against the ram stroke: offset 0 (the quick return lost) and the measured points."""
    geometry = analysis.recording.geometry
    h, height = geometry.pivot_distance, geometry.ram_height
    figure, axes = plt.subplots(figsize=(8, 5.5))
    strokes = np.linspace(0.01, 2.0 * float(geometry.ram_stroke), CURVE_POINTS)
    radii = np.asarray(crank_radius_for_stroke(strokes, h, height))
    half = np.arcsin(radii / h)
    axes.plot(strokes * 1e3, (np.pi + 2 * half) / (np.pi - 2 * half), color='C0', gid=THEORY,
              label='theory at offset 0 (eq. 28): a short stroke loses its quick return')
    rows = [r for r in analysis.rows if r['time_ratio_measured'] is not None]
    # Rows at another stroke than the recording's, with an offset: the time-ratio hold's.
    held_rows = [r for r in rows if r['offset'] != 0.0
                 and r.get('crank_radius', geometry.crank_radius) != geometry.crank_radius]
    for index, offset in enumerate(sorted({r['offset'] for r in held_rows})):
        ratios = [float(kin.time_ratio(dataclasses.replace(geometry, crank_radius=float(r)),
                                       offset)) for r in radii]
        axes.plot(strokes * 1e3, ratios, color=f'C{1 + index}', gid=THEORY, linestyle='--',
                  label=f'theory at offset {offset * 1e3:.3g} mm (the hold\'s)')
    for chosen, marker, colour, words in (
            ([r for r in rows if r['offset'] == 0.0], 'o', 'C3', 'measured, offset 0'),
            (held_rows, 's', 'C2', 'measured, the time ratio held by the offset')):
        if chosen:
            stroke = [r.get('stroke_length', float(geometry.ram_stroke)) * 1e3 for r in chosen]
            axes.errorbar(stroke, [r['time_ratio_measured'] for r in chosen],
                          yerr=[r['time_ratio_measured_std'] for r in chosen], fmt=marker,
                          color=colour, capsize=3, label=words)
    axes.axhline(1.0, color='0.6', linewidth=0.8)
    axes.set_xlabel('ram stroke S [mm]')
    axes.set_ylabel('time ratio TR = cutting time / return time [-]')
    axes.set_title(f'Time ratio against stroke, with and without the offset; h = {h * 1e3:g} '
                   f'mm, H = {height * 1e3:g} mm')
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize='small')
    return figure


def time_ratio_figure(analysis: Analysis) -> Figure:
    """TR against δ/h: the closed form (and other crank radii) and the measured means."""
    geometry = analysis.recording.geometry
    offsets = _offset_axis(geometry)
    figure, axes = plt.subplots(figsize=(8, 5.5))
    for sign in _directions(analysis):
        label = (f'theory (closed form), r = {geometry.crank_radius * 1e3:g} mm'
                 + (', reverse running' if sign < 0 else ''))
        axes.plot(offsets / geometry.pivot_distance, kin.time_ratio(geometry, offsets, sign),
                  color='C0' if sign > 0 else 'C2', gid=THEORY, label=label)
    # The paper's Fig. 10 shows a family of crank radii: other strokes, same machine.
    for crank_radius in OTHER_CRANK_RADII:
        if crank_radius != geometry.crank_radius and crank_radius < geometry.pivot_distance:
            other = kin.Geometry(geometry.coupling_radius, crank_radius,
                                 geometry.pivot_distance, geometry.ram_height,
                                 geometry.crank_phase)
            x = offsets / geometry.pivot_distance
            y = cast(np.ndarray, kin.time_ratio(other, offsets))
            axes.plot(x, y, color='0.6', linewidth=0.9, linestyle='--', gid=THEORY_FAMILY,
                      label='theory, other crank radii' if crank_radius == OTHER_CRANK_RADII[0]
                      else None)
            axes.annotate(f'r = {crank_radius * 1e3:g} mm', (x[-1], y[-1]), fontsize='small',
                          color='0.4', xytext=(3, 0), textcoords='offset points', va='center')
    x, y, spread = _measured(analysis, 'time_ratio')
    strokes = _row_strokes(analysis, 'time_ratio')
    recorded = geometry.crank_radius
    for index, radius in enumerate(sorted(set(strokes), reverse=True)):
        chosen = strokes == radius
        if radius != recorded:  # another stroke in the run: its own theory curve
            other = dataclasses.replace(geometry, crank_radius=radius)
            axes.plot(offsets / geometry.pivot_distance, kin.time_ratio(other, offsets),
                      color=f'C{4 + index}', gid=THEORY,
                      label=f'theory (closed form), r = {radius * 1e3:.4g} mm')
        axes.errorbar(x[chosen], y[chosen], yerr=spread[chosen], fmt='o',
                      color='C3' if radius == recorded else f'C{4 + index}', capsize=3,
                      label='measured (mean ± s.d. over stroke pairs)' + (
                          f', stroke {float(other.ram_stroke) * 1e3:.4g} mm'
                          if radius != recorded else ''))
    axes.axhline(1.0, color='0.6', linewidth=0.8)
    axes.set_xlabel('offset / pivot distance, δ/h [-]')
    axes.set_ylabel('time ratio TR = cutting time / return time [-]')
    axes.set_yscale('log')
    axes.set_title(f'Time ratio against offset (cf. paper Fig. 10); h = '
                   f'{geometry.pivot_distance * 1e3:g} mm, r1 = '
                   f'{geometry.coupling_radius * 1e3:g} mm')
    axes.grid(True, which='both', alpha=0.3)
    axes.legend()
    return figure


def speed_ratio_figure(analysis: Analysis) -> Figure:
    """Mid-stroke and peak SR against δ/h: the closed forms and the measured means."""
    geometry = analysis.recording.geometry
    offsets = _offset_axis(geometry)
    figure, axes = plt.subplots(figsize=(8, 5.5))
    sign = _directions(analysis)[0]
    x_theory = offsets / geometry.pivot_distance
    axes.plot(x_theory, kin.speed_ratio(geometry, offsets, sign), color='C0', gid=THEORY,
              label='mid-stroke SR, theory (eq. 25)')
    axes.plot(x_theory, kin.peak_speed_ratio(geometry, offsets, sign), color='C1',
              linestyle='--', gid=THEORY, label='peak SR, theory')
    for key, marker, color, label in (('speed_ratio', 'o', 'C3', 'mid-stroke SR, measured'),
                                      ('peak_speed_ratio', 's', 'C4', 'peak SR, measured')):
        x, y, spread = _measured(analysis, key)
        axes.errorbar(x, y, yerr=spread, fmt=marker, color=color, capsize=3, label=label,
                      markerfacecolor='none' if marker == 's' else color)
    unity = cast(float, kin.offset_for_speed_ratio(geometry, 1.0)) / geometry.pivot_distance
    axes.axhline(1.0, color='0.6', linewidth=0.8)
    axes.axvline(unity, color='0.6', linewidth=0.8, linestyle=':',
                 label=f'SR = 1 at δ/h = {unity:.4f} (eq. 26)')
    axes.set_yscale('log')
    axes.set_xlabel('offset / pivot distance, δ/h [-]')
    axes.set_ylabel('speed ratio SR = return speed / cutting speed [-]')
    axes.set_title('Speed ratio against offset (cf. paper Fig. 11)')
    axes.grid(True, which='both', alpha=0.3)
    axes.legend()
    return figure


def _one_revolution(samples, segment):
    """Return the samples of the first whole input revolution inside a segment."""
    span = np.arange(segment.start, segment.end)  # by index: stamps may jump between segments
    unwrapped = np.unwrap(samples.input_angle[span])
    travelled = np.abs(unwrapped - unwrapped[0])
    return span[travelled <= 2 * math.pi], unwrapped[travelled <= 2 * math.pi]


def _has_theory(geometry, row):
    """Whether the closed form covers a segment (a damaged file can hold any setting)."""
    return (abs(row['offset']) < geometry.coupling_radius
            and math.isfinite(row['input_speed']))


def _input_angle_grid():
    return np.linspace(0.0, 2 * math.pi, CURVE_POINTS)


def flywheel_speed_figure(analysis: Analysis) -> Figure:
    """Flywheel speed over one input revolution per segment: theory and recorded."""
    geometry = analysis.recording.geometry
    samples = analysis.recording.samples
    figure, axes = plt.subplots(figsize=(8, 5.5))
    theta = _input_angle_grid()
    for index, (row, segment) in enumerate(zip(analysis.rows, analysis.segments)):
        color = f'C{index % 10}'
        label = f'δ = {row["offset"] * 1e3:g} mm'
        if _has_theory(geometry, row):
            axes.plot(np.degrees(theta), kin.state(geometry, row['offset'], theta,
                                                   row['input_speed']).flywheel_speed,
                      color=color, gid=THEORY, label=f'{label}, theory')
        chosen, _ = _one_revolution(samples, segment)
        angle = np.mod(samples.input_angle[chosen], 2 * math.pi)
        axes.plot(np.degrees(angle), samples.flywheel_speed[chosen], '.', color=color,
                  markersize=3, label=f'{label}, recorded')
    axes.set_xlabel('input shaft angle θ [deg]')
    axes.set_ylabel('flywheel speed ω2 [rad/s]')
    axes.set_xlim(0, 360)
    axes.set_title('Flywheel speed over one input revolution (cf. paper Fig. 12)')
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize='small', ncol=2)
    return figure


def ram_motion_figure(analysis: Analysis) -> Figure:
    """Ram position and velocity over one input revolution per segment."""
    geometry = analysis.recording.geometry
    samples = analysis.recording.samples
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
    theta = _input_angle_grid()
    for index, (row, segment) in enumerate(zip(analysis.rows, analysis.segments)):
        color = f'C{index % 10}'
        label = f'δ = {row["offset"] * 1e3:g} mm'
        theory = _has_theory(geometry, row)
        if theory:
            state = kin.state(geometry, row['offset'], theta, row['input_speed'])
            top.plot(np.degrees(theta), state.ram_position * 1e3, color=color, gid=THEORY,
                     label=label)
            bottom.plot(np.degrees(theta), state.ram_velocity, color=color, gid=THEORY)
        chosen, _ = _one_revolution(samples, segment)
        angle = np.degrees(np.mod(samples.input_angle[chosen], 2 * math.pi))
        top.plot(angle, samples.ram_position[chosen] * 1e3, '.', color=color, markersize=3,
                 label=None if theory else f'{label} (no closed form)')
        bottom.plot(angle, samples.ram_velocity[chosen], '.', color=color, markersize=3)
    top.set_ylabel('ram position x [mm]')
    bottom.set_ylabel('ram velocity v [m/s] (< 0: cutting)')
    bottom.set_xlabel('input shaft angle θ [deg]')
    bottom.set_xlim(0, 360)
    top.set_title('Ram position and velocity over one input revolution (lines: theory, '
                  'dots: recorded)')
    for axes in (top, bottom):
        axes.grid(True, alpha=0.3)
    top.legend(fontsize='small', ncol=2)
    return figure


# Effort figures. Theory lines of the input torque's parts carry these gids.
TORQUE_PARTS = {'total': ('total, theory', '-', 'C0'),
                'inertia': ('inertia part', '--', 'C1'),
                'cutting': ('cutting part', ':', 'C2'),
                'gravity_and_friction': ('gravity and friction', '-.', 'C4')}
MAX_TORQUE_PANELS = 8  # segments drawn in the input torque figure (the first ones)
COST_CURVE_POINTS = 21  # offsets of the peak-torque theory curve (each an exact integral)


def _no_data(axes, text):
    axes.text(0.5, 0.5, text, transform=axes.transAxes, ha='center', va='center',
              color='0.4', wrap=True)


def input_torque_figure(analysis: Analysis) -> Figure:
    """Input torque over one revolution per segment: recorded, theory and its parts."""
    recording = analysis.recording
    geometry, samples = recording.geometry, recording.samples
    shown = list(zip(analysis.rows, analysis.segments))[:MAX_TORQUE_PANELS]
    count = max(len(shown), 1)
    figure, panels = plt.subplots(count, 1, figsize=(8, 2.6 * count + 1.0), sharex=True,
                                  squeeze=False)
    theta = _input_angle_grid()
    for axes, (row, segment) in zip(panels[:, 0], shown):
        drive = segment.drive  # the masses and loads in force there
        axes.set_title(f'δ = {row["offset"] * 1e3:g} mm (δ/h = '
                       f'{row["offset_over_pivot_distance"]:+.4f}), '
                       f'{row["input_speed"]:g} rad/s', fontsize='medium')
        if drive is not None and _has_theory(geometry, row) and row['input_speed'] != 0.0:
            parts = input_torque_parts(geometry, drive, row['offset'], theta,
                                       row['input_speed'])
            for name, (label, style, color) in TORQUE_PARTS.items():
                axes.plot(np.degrees(theta), getattr(parts, name), linestyle=style, color=color,
                          linewidth=1.6 if name == 'total' else 1.0, gid=name, label=label)
        if samples.input_torque is not None:
            chosen, _ = _one_revolution(samples, segment)
            angle = np.mod(samples.input_angle[chosen], 2 * math.pi)
            axes.plot(np.degrees(angle), samples.input_torque[chosen], '.', color='C3',
                      markersize=3, gid='recorded', label='recorded')
        elif drive is None:
            _no_data(axes, 'input torque not recorded; no theory ('
                     f'{recording.drive_problem})')
        else:
            _no_data(axes, 'input torque not recorded (lines: theory)')
        if drive is None and samples.input_torque is not None:
            axes.text(0.01, 0.97, f'no theory: {recording.drive_problem}',
                      transform=axes.transAxes, va='top', fontsize='small', color='0.4')
        axes.axhline(0.0, color='0.6', linewidth=0.8)
        axes.set_ylabel('input torque T1 [N m]')
        axes.grid(True, alpha=0.3)
    if not shown:
        _no_data(panels[0, 0], 'no segment of steady offset and input speed')
    handles = {label: handle for axes in panels[:, 0]
               for handle, label in zip(*axes.get_legend_handles_labels())}
    if handles:
        panels[0, 0].legend(handles.values(), handles.keys(), fontsize='small', ncol=3)
    panels[-1, 0].set_xlabel('input shaft angle θ [deg]')
    panels[-1, 0].set_xlim(0, 360)
    omitted = len(analysis.rows) - len(shown)
    figure.suptitle('Input torque over one revolution (speed drive at steady speed; inertia '
                    'part: no gravity, no loads)' + (f'; {omitted} more segments not shown'
                                                     if omitted > 0 else ''),
                    fontsize='medium')
    return figure


def _cost_speeds(analysis):
    """Return the segments' input speeds (the peak torque grows with the speed squared)."""
    return sorted({row['input_speed'] for row in analysis.rows
                   if row['input_speed'] != 0.0 and math.isfinite(row['input_speed'])})


def offset_cost_figure(analysis: Analysis) -> Figure:
    """Peak input torque and flywheel speed swing against δ/h: what the offset costs."""
    recording = analysis.recording
    geometry, drive = recording.geometry, recording.drive
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
    h = geometry.pivot_distance
    if drive is not None:
        offsets = np.linspace(-geometry.max_safe_offset, geometry.max_safe_offset,
                              COST_CURVE_POINTS)
        for index, speed in enumerate(_cost_speeds(analysis)[:4]):
            peaks = [pair_efforts(geometry, drive.mass, drive.loads, offset, speed
                                  ).peak_input_torque for offset in offsets]
            top.plot(offsets / h, peaks, '-', color=f'C{index}', gid=THEORY,
                     label=f'theory (ideal speed drive), {speed:g} rad/s')
    else:
        _no_data(top, f'no theory: {recording.drive_problem}')
    rows = [r for r in analysis.rows if r['peak_input_torque_measured'] is not None]
    if rows:
        top.errorbar([r['offset_over_pivot_distance'] for r in rows],
                     [r['peak_input_torque_measured'] for r in rows],
                     yerr=[r['peak_input_torque_measured_std'] for r in rows], fmt='o',
                     color='C3', capsize=3, label='measured (mean ± s.d. over stroke pairs)')
    elif recording.samples.input_torque is None:
        top.text(0.01, 0.03, 'input torque not recorded', transform=top.transAxes,
                 color='0.4')
    top.set_yscale('log')  # it grows without bound toward the largest offsets
    top.set_ylabel('peak |input torque| per stroke pair [N m]')
    top.set_title('What the offset costs: peak input torque and flywheel speed swing')
    offsets = _offset_axis(geometry)
    bottom.plot(offsets / h, flywheel_speed_swing(geometry, offsets), color='C0', gid=THEORY,
                label='theory, (r1 + |δ|) / (r1 - |δ|) (eq. 4)')
    x, y, spread = _measured(analysis, 'flywheel_speed_swing')
    bottom.errorbar(x, y, yerr=spread, fmt='o', color='C3', capsize=3,
                    label='measured (mean ± s.d. over stroke pairs)')
    bottom.set_yscale('log')
    bottom.set_ylabel('flywheel speed swing max ω2 / min ω2 [-]')
    bottom.set_xlabel('offset / pivot distance, δ/h [-]')
    for axes in (top, bottom):
        axes.grid(True, which='both', alpha=0.3)
        if axes.get_legend_handles_labels()[0]:
            axes.legend(fontsize='small')
    return figure


FIGURES: Dict[str, Callable[[Analysis], Figure]] = {
    'fig10_time_ratio.png': time_ratio_figure,
    'fig_time_ratio_stroke.png': time_ratio_stroke_figure,
    'fig11_speed_ratio.png': speed_ratio_figure,
    'fig12_flywheel_speed.png': flywheel_speed_figure,
    'ram_motion.png': ram_motion_figure,
    'fig_input_torque.png': input_torque_figure,
    'fig_offset_cost.png': offset_cost_figure,
}


def write_figures(analysis: Analysis, directory: str,
                  stage: Optional[Callable[[str], str]] = None) -> List[str]:
    """
    Write every figure as PNG into directory (created); return the paths.

    ``stage`` (from qrm_ros.recording.atomic_files.staged_outputs) maps each path to the
    temporary name to write, so the figures appear together with the other outputs or not at all.
    """
    os.makedirs(directory, exist_ok=True)
    paths = []
    for name, build in FIGURES.items():
        figure = build(analysis)
        path = os.path.join(directory, name)
        try:
            # tight_layout leaves no room for a suptitle by itself: keep 0.35 inch for it.
            top = 1.0 - 0.35 / figure.get_figheight() if figure.get_suptitle() else 1.0
            figure.tight_layout(rect=(0.0, 0.0, 1.0, top))
            figure.savefig(path if stage is None else stage(path), dpi=110, format='png')
        finally:
            plt.close(figure)
        paths.append(path)
    return paths
