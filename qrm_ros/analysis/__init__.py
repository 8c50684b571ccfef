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

import lazy_loader

# The names of __init__.pyi, each loaded from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
