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
``mcap_replay`` and ``simulated_run``. See doc/testing.md.
"""

from qrm_ros.testing.kit import (EXAMPLES_FOLDER, example_names, example_recording,
                                 example_scenario, McapReplay, RosProcess, simulate,
                                 spin_until, start_shaper_sim, wait_for_topics)

__all__ = ['EXAMPLES_FOLDER', 'McapReplay', 'RosProcess', 'example_names', 'example_recording',
           'example_scenario', 'simulate', 'spin_until', 'start_shaper_sim', 'wait_for_topics']
