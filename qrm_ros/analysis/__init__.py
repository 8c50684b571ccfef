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
Offline analysis of recorded runs: measurement, reports, figures, animations, design tables.

A script needs no more than::

    from qrm_ros.analysis import analyse, format_table, read_recording
    print(format_table(analyse(read_recording('run.mcap'))))

The rooms: recorded_run (reading a run: samples, geometry; joint_state_decoding and
recorded_drive beneath it), segments (steady spans), measurement (per segment, against
theory), report (table, CSV, JSON), figures and gearbox_figure (matplotlib), animation and
linkage_figure (GIF, MP4), design_table (qrm_design's tables).

The names below are loaded on first use, from the module that defines them: importing one
module of the package (qrm_design's design_table, say) does not load the run reader.
"""

import importlib
from typing import Any, TYPE_CHECKING

# Re-exported name -> the module of qrm_ros.analysis that defines it.
_HOMES = {
    'AnalysisError': 'recorded_run', 'Recording': 'recorded_run',
    'read_recording': 'recorded_run',
    'Analysis': 'measurement', 'analyse': 'measurement',
    'format_table': 'report', 'incompleteness': 'report', 'to_document': 'report',
    'write_outputs': 'report',
}

__all__ = sorted(_HOMES)

if TYPE_CHECKING:  # the same names, for type checkers and readers
    from qrm_ros.analysis.measurement import analyse, Analysis  # noqa: F401
    from qrm_ros.analysis.recorded_run import (AnalysisError, read_recording,  # noqa: F401
                                               Recording)
    from qrm_ros.analysis.report import (format_table, incompleteness,  # noqa: F401
                                         to_document, write_outputs)


def __getattr__(name: str) -> Any:
    """Return a re-exported name, importing its module on first use (PEP 562)."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'{__name__}.{home}'), name)
