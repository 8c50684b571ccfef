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
"""Fixtures the analysis tests share."""

import pytest

from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_run
from synthetic_run import PAPER, samples_for, SCHEDULE


@pytest.fixture(scope='module')
def schedule_analysis():
    """Analyse the paper's machine along SCHEDULE, from samples made without ROS."""
    recording = recorded_run.Recording('synthetic', PAPER, samples_for(SCHEDULE), None)
    return measurement.analyse(recording)
