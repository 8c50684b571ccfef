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
A test kit for the test suites of nodes that consume a shaper drive's topics.

Start shaper_sim or a player of a recorded run for the length of a test, wait for topics,
simulate a scenario into a run file, and use the example runs shipped with the package
(``example_recording('steady_offset')``). The pytest plugin (qrm_ros.testing.plugin, on
once the package is installed) offers the same as the fixtures ``shaper_sim_process``,
``mcap_replay`` and ``simulated_run``. Compare two runs field by field, bit for bit or
within ulps (``assert_runs_match(made, example_recording('steady_offset'))``), bit for bit
where ``reference_math()`` says this machine is of the kind the examples were made on. See
doc/testing.md and doc/reproducibility.md.
"""

from qrm_ros.testing.compare import (assert_runs_match, first_difference, LOG_TIME, MESSAGE_COUNT,
                                     MESSAGE_TYPE, RunDifference, RunSource, ulp_distance)
from qrm_ros.testing.reference_math import OTHER_MACHINE_RELATIVE, REFERENCE_GLIBC, reference_math
from qrm_ros.testing.kit import (EXAMPLES_FOLDER, example_names, example_recording,
                                 example_scenario, McapReplay, RosProcess, simulate, spin_until,
                                 start_shaper_sim, wait_for_topics)

__all__ = ['EXAMPLES_FOLDER', 'LOG_TIME', 'MESSAGE_COUNT', 'MESSAGE_TYPE', 'McapReplay',
           'OTHER_MACHINE_RELATIVE', 'REFERENCE_GLIBC', 'RosProcess', 'RunDifference',
           'RunSource', 'assert_runs_match', 'example_names', 'example_recording',
           'example_scenario', 'first_difference', 'reference_math', 'simulate', 'spin_until',
           'start_shaper_sim', 'ulp_distance', 'wait_for_topics']
