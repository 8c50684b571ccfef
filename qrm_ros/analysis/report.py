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
What an analysis tells: the table a person reads, the CSV, the JSON, and what was lost.

The outputs are written all or none (qrm_ros.recording.atomic_files): a failure leaves no
half-written file. JSON holds null where a figure is not finite.
"""

import contextlib
import csv
import json
import math
import os
from typing import Any, Dict, List, Optional, Tuple

from qrm_ros.analysis.joint_state_decoding import JOINT_STATES_TOPIC
from qrm_ros.analysis.measurement import (ALL_BOUNDED_FIGURES, Analysis, finite_or_none,
                                          relative_bound)
from qrm_ros.analysis.recorded_run import IN_EFFORTS, IN_FILE, IN_MESSAGE, Recording
from qrm_ros.core.measurement.sampling_bounds import SUPPORTED_RELATIVE_ERROR
from qrm_ros.recording.atomic_files import staged_outputs

# Below this, the between-sample interpolation can miss sharp speed peaks (large offsets).
MIN_SAMPLES_PER_REVOLUTION = 60
_LOSS_VERBS = {IN_FILE: 'lost', IN_MESSAGE: 'excluded', IN_EFFORTS: 'used without their efforts'}


def _fmt(value, spec):
    width = spec.lstrip('+-').split('.')[0]
    return format('-', '>' + width) if value is None else format(value, spec)


def format_table(analysis: Analysis) -> str:
    """Return the per-segment table a person reads, with warnings and transitions."""
    recording = analysis.recording
    geometry = recording.geometry
    lines = [
        f'{recording.path}: {recording.sample_count} joint-state samples over '
        f'{recording.time_span:.3f} s',
        f'geometry: r1 = {geometry.coupling_radius * 1e3:g} mm, r = '
        f'{geometry.crank_radius * 1e3:g} mm, h = {geometry.pivot_distance * 1e3:g} mm, '
        f'H = {geometry.ram_height * 1e3:g} mm, crank phase = {geometry.crank_phase:g} rad',
        '',
        ' offset  offset/h    input  pairs |      TR measured  TR theory  rel.err sampling |'
        '      SR measured  SR theory  rel.err sampling | peak SR measured  theory   rel.err'
        ' sampling',
        '   [mm]       [-]  [rad/s]    [-] |                                       (rel.) |'
        '                                       (rel.) |                                '
        '  (rel.)',
    ]
    for row in analysis.rows:
        parts = [f'{row["offset"] * 1e3:7.2f} {row["offset_over_pivot_distance"]:+9.5f} '
                 f'{row["input_speed"]:8.4f} {row["stroke_pairs"]:6d} |']
        for name in ('time_ratio', 'speed_ratio', 'peak_speed_ratio'):
            mean, spread = row[f'{name}_measured'], row[f'{name}_measured_std']
            measured = '-' if mean is None else f'{mean:8.5f} ± {spread:.1e}'
            parts.append(f' {measured:>16} {_fmt(row[name + "_theory"], "10.5f")} '
                         f'{_fmt(row[name + "_relative_error"], "+8.1e")} '
                         f'{_sampling_column(row, name)} |')
        lines.append(''.join(parts)[:-2])
    if not analysis.rows:
        lines.append('  (no segment of steady offset and input speed)')
    for number, row in enumerate(analysis.rows, 1):
        if row.get('stroke_length') is not None:  # recorded with the crank radius joint
            lines.append(f'segment {number}: stroke {row["stroke_length"] * 1e3:.3f} mm, crank '
                         f'radius {row["crank_radius"] * 1e3:.4f} mm')
    lines += _effort_lines(analysis)
    for row in analysis.rows:
        per_turn = row['samples_per_revolution']
        if per_turn is not None and per_turn < MIN_SAMPLES_PER_REVOLUTION:
            lines.append(
                f'warning: offset {row["offset"] * 1e3:g} mm at {row["input_speed"]:g} rad/s '
                f'has only {per_turn:.0f} samples per input revolution (fewer than '
                f'{MIN_SAMPLES_PER_REVOLUTION}): reversals and peaks between samples are '
                'uncertain; record at a higher publish_rate')
    for t in analysis.transitions:
        lines.append(f'transition {t["start_time"]:.3f}-{t["end_time"]:.3f} s excluded: '
                     f'{t["change"]}')
    if recording.repeated_stamps:
        lines.append(f'note: {recording.repeated_stamps} messages repeat the previous one '
                     '(same stamp, same values) and were counted once')
    return '\n'.join(lines)


def _sampling_column(row: Dict[str, Any], name: str) -> str:
    """Format the figure's sampling bound relative to it; 'none' where no bound holds."""
    if row.get(f'{name}_measured') is None:
        return format('-', '>8')
    relative = sampling_relative_bound(row, name)
    return format('none' if relative is None else format(relative, '8.1e'), '>8')


def sampling_relative_bound(row: Dict[str, Any], name: str) -> Optional[float]:
    """Return a figure's sampling bound over its theory (measurement.relative_bound)."""
    return relative_bound(row, name, row.get(f'{name}_sampling_bound'))


def unsupported_by_sampling(analysis: Analysis) -> List[str]:
    """One line per figure kind that the sampling cannot support to SUPPORTED_RELATIVE_ERROR."""
    lines = []
    problems = {row.get('sampling_bound_problem') for row in analysis.rows}
    for problem in sorted(str(problem) for problem in problems if problem):
        rows = [row for row in analysis.rows if row.get('sampling_bound_problem') == problem]
        lines.append(f'no figure of {len(rows)} of {len(analysis.rows)} segments is supported '
                     f'to {SUPPORTED_RELATIVE_ERROR:g} by the sampling: {problem}')
    for name in ALL_BOUNDED_FIGURES:
        worst: List[Tuple[float, Dict[str, Any]]] = []
        for row in analysis.rows:
            if row.get(f'{name}_measured') is None or row.get('sampling_bound_problem'):
                continue
            relative = sampling_relative_bound(row, name)
            if relative is None or relative > SUPPORTED_RELATIVE_ERROR:
                worst.append((math.inf if relative is None else relative, row))
        if not worst:
            continue
        relative, row = max(worst, key=lambda item: item[0])
        per_turn = row['samples_per_revolution']
        said = ('cannot be bounded' if math.isinf(relative)
                else f'may be off by up to {relative:.1e} relative')
        lines.append(
            f'{FIGURE_WORDS.get(name, name)} is not supported to '
            f'{SUPPORTED_RELATIVE_ERROR:g} by the sampling in {len(worst)} of '
            f'{len(analysis.rows)} segments: at offset {row["offset"] * 1e3:g} mm, '
            f'{row["input_speed"]:g} rad/s'
            + ('' if per_turn is None else f' ({per_turn:.1f} samples per input revolution)')
            + f' it {said}; record at a higher publish_rate')
    for row in analysis.rows:
        turns = (abs(row['input_speed']) * (row['end_time'] - row['start_time'])
                 / (2 * math.pi))
        if row['stroke_pairs'] == 0 and turns >= MISSED_STROKE_TURNS:
            lines.append(
                f'no stroke pair was found at offset {row["offset"] * 1e3:g} mm, '
                f'{row["input_speed"]:g} rad/s in {turns:.1f} input revolutions: a stroke '
                'falls between samples (a reversal the sampling cannot see); record at a '
                'higher publish_rate')
    return lines


# A segment this many input revolutions long holds a stroke pair, unless the sampling
# misses its strokes.
MISSED_STROKE_TURNS = 2.5


# How a warning names each bounded figure.
FIGURE_WORDS = {'time_ratio': 'the time ratio TR', 'speed_ratio': 'the speed ratio SR',
                'peak_speed_ratio': 'the peak speed ratio', 'cutting_time': 'the cutting time',
                'return_time': 'the return time', 'peak_cutting_speed': 'the peak cutting speed',
                'peak_return_speed': 'the peak return speed',
                'flywheel_speed_swing': 'the flywheel speed swing',
                'peak_input_torque': 'the peak input torque',
                'rms_input_torque': 'the RMS input torque',
                'mean_input_power': 'the mean input power',
                'energy_per_pair': 'the energy per stroke pair',
                'peak_offset_force': 'the peak offset force',
                'speed_fluctuation': 'the input speed fluctuation Cs'}


# Rows of the effort block: figure, what it is [unit], value format.
_EFFORT_ROWS = (
    ('peak_input_torque', 'peak |input torque| [N m]', '10.4f'),
    ('rms_input_torque', 'RMS input torque [N m]', '10.4f'),
    ('mean_input_power', 'mean input power [W]', '10.4f'),
    ('energy_per_pair', 'energy per stroke pair [J]', '10.4f'),
    ('peak_offset_force', 'peak |offset force| [N]', '10.3f'),
    ('speed_fluctuation', 'input speed fluctuation Cs [-]', '10.2e'),
    ('flywheel_speed_swing', 'flywheel speed max/min [-]', '10.6f'),
)


def _effort_lines(analysis: Analysis) -> List[str]:
    """Return the drive's figures per segment: measured mean ± s.d., theory, error."""
    recording = analysis.recording
    if not analysis.rows:
        return []
    drive = recording.drive
    lines = ['']
    if drive is None:
        lines.append(f'efforts: no theory ({recording.drive_problem})')
    else:
        kind = ('ideal speed drive' if drive.motor is None else
                f'motor drive, {drive.motor.speed_stiffness:g} N m s/rad, '
                f'{drive.motor.max_torque:g} N m')
        lines.append(f'efforts: theory for the recorded masses and loads, {kind} (cutting '
                     f'{drive.loads.cutting_force:g} N over {drive.loads.cutting_length:g} m, '
                     f'friction {drive.loads.ram_friction:g} N)')
    if not recording.efforts_recorded:
        lines.append('efforts: not recorded in this file (joint states without effort)')
    for row in analysis.rows:
        lines.append(f'  offset {row["offset"] * 1e3:.2f} mm at {row["input_speed"]:.4f} rad/s, '
                     f'{row["stroke_pairs_with_efforts"]} of {row["stroke_pairs"]} stroke pairs '
                     'with efforts:        measured       theory     error sampling')
        if row.get('stroke_pairs_left_out_of_efforts'):
            lines.append(f'    ({row["stroke_pairs_left_out_of_efforts"]} of them left out of '
                         'these figures: sampled too coarsely around a peak or a switch to '
                         f'support their efforts to {SUPPORTED_RELATIVE_ERROR:g})')
        for name, title, spec in _EFFORT_ROWS:
            mean, spread = row[f'{name}_measured'], row[f'{name}_measured_std']
            measured = '-' if mean is None else f'{format(mean, spec)} ± {spread:.1e}'
            if row.get(f'{name}_theory') == 0.0:
                error = _fmt(row[f'{name}_absolute_error'], '+9.1e') + ' (abs.)'
            else:
                error = _fmt(row[f'{name}_relative_error'], '+9.1e')
            lines.append(f'    {title:<32} {measured:>20} {_fmt(row[name + "_theory"], spec)} '
                         f'{error} {_sampling_column(row, name)}')
        if row.get('effort_theory_problem'):
            lines.append(f'    theory missing: {row["effort_theory_problem"]}')
    return lines


def misplaced_stamp_lines(analysis: Analysis) -> List[str]:
    """Lines naming samples left out for a stamp the input shaft's advance contradicts."""
    return [f'{len(row["misplaced_stamps"])} {JOINT_STATES_TOPIC} messages excluded from the '
            f'segment at offset {row["offset"]:.10g} m, {row["input_speed"]:.6g} rad/s (at '
            + ', '.join(f'{time:.6f}' for time in row['misplaced_stamps'][:5])
            + (', ...' if len(row['misplaced_stamps']) > 5 else '')
            + ' s): their stamps contradict the input angle\'s advance at a constant speed '
            '(closed form, check stamp)'
            for row in analysis.rows if row.get('misplaced_stamps')]


def theory_shortfalls(analysis: Analysis) -> List[str]:
    """Lines saying where the theory could not be worked out within its bound (exit 3)."""
    return [f'segment at offset {row["offset"]:.10g} m, {row["input_speed"]:.6g} rad/s: no '
            f'effort theory: {row["effort_theory_problem"]}'
            for row in analysis.rows if row.get('effort_theory_problem')]


def incompleteness(recording: Recording) -> List[str]:
    """Lines saying what the analysis lacks; empty when the recording was read whole."""
    lines = []
    if recording.problem:
        lines.append(f'{recording.path} is damaged or truncated: {recording.problem}')
    lines += [f'{recording.path}: {span.problem}' for span in recording.drive_changes
              if span.unreadable]
    for loss in recording.losses:
        count = ('an unknown number of' if loss.messages is None else
                 f'{loss.messages}')
        when = ''
        if loss.start_time is not None:
            when = (f', log time {loss.start_time:.3f} s' + (
                '' if loss.end_time is None else f' to {loss.end_time:.3f} s')
                + ' after the first message')
        verb = _LOSS_VERBS[loss.stage]
        lines.append(f'{count} {JOINT_STATES_TOPIC} messages {verb}{when}: {loss.reason}')
    return lines


def shortfalls(analysis: Analysis) -> Tuple[List[str], List[str]]:
    """
    Return what an analysis lacks: (what the data lacks, what the sampling cannot support).

    One rule for every command that reports an analysis (qrm_analyze, its fleet, qrm_main):
    either list non-empty means exit 3; both empty, the figures stand as printed.
    """
    return (incompleteness(analysis.recording) + misplaced_stamp_lines(analysis)
            + theory_shortfalls(analysis), unsupported_by_sampling(analysis))


def to_document(analysis: Analysis) -> Dict[str, Any]:
    """Return the JSON document of an analysis (no NaN or infinity: null instead)."""
    recording = analysis.recording
    return finite_or_none({
        'file': recording.path,
        'complete': recording.complete,
        'truncated': recording.problem,
        'units': 'SI (m, s, rad, rad/s, m/s); ratios dimensionless',
        'geometry': recording.geometry.as_dict(),
        'messages': {'in_file': recording.messages_in_file, 'read': recording.messages_read,
                     'used': recording.sample_count,
                     'repeated': recording.repeated_stamps},
        'losses': [loss._asdict() for loss in recording.losses],
        'segments': analysis.rows,
        'transitions': analysis.transitions,
    })


def write_csv_to(analysis: Analysis, path: str) -> None:
    """Write the per-segment table as CSV to path (a staged name: see write_outputs)."""
    fields = list(analysis.rows[0]) if analysis.rows else ['offset']
    with open(path, 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for row in finite_or_none(analysis.rows):
            writer.writerow({k: ('' if v is None else v) for k, v in row.items()})


def write_json_to(analysis: Analysis, path: str) -> None:
    """Write the results as JSON to path (a staged name: see write_outputs)."""
    with open(path, 'w') as handle:
        json.dump(to_document(analysis), handle, indent=2, allow_nan=False)
        handle.write('\n')


def write_csv(analysis: Analysis, path: str) -> None:
    """Write the per-segment table as CSV, all or nothing."""
    with staged_outputs() as stage:
        write_csv_to(analysis, stage(path))


def write_json(analysis: Analysis, path: str) -> None:
    """Write the results as JSON, all or nothing."""
    with staged_outputs() as stage:
        write_json_to(analysis, stage(path))


def write_outputs(analysis: Analysis, csv_path: Optional[str] = None,
                  json_path: Optional[str] = None, plot_folder: Optional[str] = None
                  ) -> List[str]:
    """Write the asked-for outputs together, all or none; return the figure paths."""
    figure_paths: List[str] = []
    created = plot_folder is not None and not os.path.isdir(plot_folder)
    try:
        with staged_outputs() as stage:
            if csv_path:
                write_csv_to(analysis, stage(csv_path))
            if json_path:
                write_json_to(analysis, stage(json_path))
            if plot_folder:
                os.makedirs(plot_folder, exist_ok=True)
                from qrm_ros.analysis.figures import write_figures
                figure_paths = write_figures(analysis, plot_folder, stage)
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                os.rmdir(plot_folder)  # type: ignore[arg-type]
        raise
    return figure_paths
