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
The one list of what qrm_ros.analysis exports, and from where.

lazy_loader reads it at run time (each name loads with its module on first use); type
checkers read it as the package's interface (``name as name``: a stub's import re-exports
only in that form).
"""

from .measurement import (analyse as analyse, Analysis as Analysis)
from .recorded_run import (AnalysisError as AnalysisError, read_recording as read_recording,
                           Recording as Recording)
from .report import (format_table as format_table, incompleteness as incompleteness,
                     shortfalls as shortfalls, to_document as to_document,
                     write_outputs as write_outputs)
from .streamed_run import (analyse_file as analyse_file)
