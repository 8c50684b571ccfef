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

The rooms: recorded_run (reading a run: samples, geometry; joint_state_decoding,
sample_checks and recorded_drive beneath it), segments (steady spans), measurement (per
segment, against theory), streamed_run (a run of any length in bounded memory: what
qrm_analyze runs), fleet and fleet_figure (many runs, on local cores or a Dask cluster),
report (table, CSV, JSON), figures and gearbox_figure (matplotlib), animation and
linkage_figure (GIF, MP4), design_table (qrm_design's tables).

The names below are loaded on first use, from the module that defines them: importing one
module of the package (qrm_design's design_table, say) does not load the run reader.
"""

from typing import TYPE_CHECKING

from qrm_ros.core.exports import declared_exports, lazy_attributes

if TYPE_CHECKING:  # the one list of what this package exports (qrm_ros.core.exports)
    from qrm_ros.analysis.measurement import analyse, Analysis
    from qrm_ros.analysis.recorded_run import AnalysisError, read_recording, Recording
    from qrm_ros.analysis.report import (format_table, incompleteness, shortfalls, to_document,
                                         write_outputs)
    from qrm_ros.analysis.streamed_run import analyse_file

EXPORTED_FROM = declared_exports(__file__)  # name -> the module that defines it
__all__ = sorted(EXPORTED_FROM, key=str.lower)
__getattr__, __dir__ = lazy_attributes(globals(), EXPORTED_FROM)
