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
The speed ladder of a gearbox plan, with and without the offset.

Left, the ray diagram machine-tool designers draw (log-log, cutting speed against input
speed): each step's reach between the rays of the slowest and fastest offset, its band
shaded. Right, the sawtooth chart: the cutting speed obtained over the one wanted, 1 with
the offset, down to 1/phi without. Artists carry gids so tests can read the data drawn.
"""

import os

from matplotlib.figure import Figure
import numpy as np

from qrm_ros.analysis.plotting import plt
from qrm_ros.core.design.gearbox import ConventionalGearbox, GearboxPlan
from qrm_ros.recording.atomic_files import staged_outputs

BAND = 'band'
REACH = 'reach'
CONVENTIONAL = 'conventional'
SAWTOOTH = 'sawtooth'
WITH_OFFSET = 'with-offset'
SAWTOOTH_POINTS = 2000


def conventional_for(plan: GearboxPlan, progression_ratio: float) -> ConventionalGearbox:
    """Return the plan's conventional gearbox with this progression ratio."""
    for box in plan.conventional:
        if box.progression_ratio == progression_ratio:
            return box
    raise ValueError(f'no conventional gearbox with progression ratio {progression_ratio!r} '
                     f'in the plan (it has {[b.progression_ratio for b in plan.conventional]})')


def obtained_without_offset(box: ConventionalGearbox, wanted: np.ndarray) -> np.ndarray:
    """Cutting speed obtained without offset: the fastest step not above the wanted one."""
    speeds = np.asarray(box.cutting_speeds)
    index = np.searchsorted(speeds, wanted, side='right') - 1
    return speeds[np.clip(index, 0, None)]


def speed_ladder_figure(plan: GearboxPlan, progression_ratio: float = 1.41) -> Figure:
    """Draw the ray diagram and the sawtooth chart of a plan, beside one conventional box."""
    box = conventional_for(plan, progression_ratio)
    figure, (rays, saw) = plt.subplots(1, 2, figsize=(12, 5.5))
    offsets = plan.offsets
    speeds = np.array([step.input_speed for step in plan.steps] + list(box.input_speeds))
    span = np.geomspace(speeds.min() / 1.5, speeds.max() * 1.5, 50)
    for unit, offset, style in ((offsets.fastest_per_input_speed, offsets.offset_at_fastest, '--'),
                                (offsets.slowest_per_input_speed, offsets.offset_at_slowest, ':')):
        rays.plot(span, unit * span, style, color='0.5', linewidth=0.9,
                  label=f'ray at offset {offset * 1e3:.3g} mm')
    unit_zero = box.cutting_speeds[0] / box.input_speeds[0]
    rays.plot(span, unit_zero * span, '-', color='C1', linewidth=0.8, label='ray at offset 0')
    for number, step in enumerate(plan.steps, 1):
        rays.plot([step.input_speed] * 2, [offsets.slowest_per_input_speed * step.input_speed,
                                           offsets.fastest_per_input_speed * step.input_speed],
                  color='C0', linewidth=1.0, gid=REACH)
        rays.plot([step.input_speed] * 2, [step.cutting_speed_min, step.cutting_speed_max],
                  color='C0', linewidth=6, solid_capstyle='butt', gid=BAND,
                  label='with offset: band served by each step' if number == 1 else None)
        rays.axhspan(step.cutting_speed_min, step.cutting_speed_max,
                     color='C0' if number % 2 else 'C9', alpha=0.12)
    rays.plot(box.input_speeds, box.cutting_speeds, 'o', color='C1', gid=CONVENTIONAL,
              label=f'without offset, phi = {box.progression_ratio:g} ({box.step_count} steps)')
    rays.set(xscale='log', yscale='log', xlabel='input speed [rad/s]',
             ylabel=f'{plan.definition} cutting speed [m/s]',
             title=f'Ray diagram: {len(plan.steps)} steps with offset, {box.step_count} without')
    rays.legend(fontsize='small', loc='upper left')
    wanted = np.geomspace(plan.min_cutting_speed, plan.max_cutting_speed, SAWTOOTH_POINTS)
    for number, step in enumerate(plan.steps, 1):
        saw.axvspan(step.cutting_speed_min, step.cutting_speed_max, gid=BAND,
                    color='C0' if number % 2 else 'C9', alpha=0.18)
        saw.annotate(f'step {number}', (np.sqrt(step.cutting_speed_min * step.cutting_speed_max),
                                        1.01), ha='center', fontsize='small', color='C0')
    saw.plot(wanted, np.ones_like(wanted), color='C0', gid=WITH_OFFSET,
             label='with offset (exact)')
    saw.plot(wanted, obtained_without_offset(box, wanted) / wanted, color='C1', gid=SAWTOOTH,
             label=f'without offset, phi = {box.progression_ratio:g}')
    saw.axhline(1.0 - box.max_shortfall, color='C1', linewidth=0.8, linestyle=':')
    saw.set(xscale='log', xlabel=f'wanted {plan.definition} cutting speed [m/s]',
            ylabel='obtained / wanted cutting speed [-]',
            ylim=(max(0.0, 0.9 - box.max_shortfall), 1.06),
            title='Sawtooth chart (bands shaded per step)')
    saw.legend(fontsize='small', loc='lower left')
    return figure


def write_speed_ladder(plan: GearboxPlan, path: str, progression_ratio: float = 1.41) -> None:
    """Write the figure atomically; the format follows the name's extension (default PNG)."""
    figure = speed_ladder_figure(plan, progression_ratio)
    extension = os.path.splitext(path)[1].lstrip('.').lower() or 'png'
    try:
        figure.tight_layout()
        with staged_outputs() as stage:
            figure.savefig(stage(path), dpi=110, format=extension)
    finally:
        plt.close(figure)
