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
The fleet's figure: the measured TR's relative error against the offset, every recording.

One marker per steady segment (δ/h of its recording's geometry, so machines of different
sizes share the axis), one colour per recording; a recording that drifts from the closed
form stands out among the others.
"""

import os
from typing import Any, Sequence

from qrm_ros.analysis.plotting import plt

MAX_LEGEND_ENTRIES = 12  # beyond this, the recordings are not named one by one


def time_ratio_error_figure(results: Sequence[Any], path: str) -> None:
    """Draw TR error against δ/h for every analysed file of results (FileResult); save PNG."""
    figure, axes = plt.subplots(figsize=(8, 5.5))
    try:
        drawn = 0
        for index, result in enumerate(results):
            if result.analysis is None:
                continue
            rows = [row for row in result.analysis.rows
                    if row['time_ratio_relative_error'] is not None]
            if not rows:
                continue
            drawn += 1
            axes.plot([row['offset_over_pivot_distance'] for row in rows],
                      [row['time_ratio_relative_error'] for row in rows], 'o',
                      color=f'C{index % 10}', markersize=4, gid='recording',
                      label=os.path.basename(result.path))
        if not drawn:
            axes.text(0.5, 0.5, 'no segment with a measured and a theoretical TR',
                      transform=axes.transAxes, ha='center', va='center', color='0.4')
        elif drawn <= MAX_LEGEND_ENTRIES:
            axes.legend(fontsize='small')
        axes.axhline(0.0, color='0.6', linewidth=0.8)
        axes.set_xlabel('offset / pivot distance, δ/h [-]')
        axes.set_ylabel('TR relative error, measured / theory - 1 [-]')
        axes.set_title(f'Time ratio against the closed form over {len(results)} recordings')
        axes.grid(True, alpha=0.3)
        figure.tight_layout()
        figure.savefig(path, dpi=110, format='png')
    finally:
        plt.close(figure)
