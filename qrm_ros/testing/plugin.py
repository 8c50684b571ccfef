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
The pytest plugin of qrm_ros (registered with the ``pytest11`` entry point, so installed means on).

At start-up it gives the test run a ROS domain no other run on the machine holds and keeps
discovery on this host (qrm_ros.node.process.ros_isolation), so the processes the fixtures start
and the test's own nodes see each other and nothing else; ``QRM_ROS_ISOLATE=0`` leaves the
environment alone. The fixtures:

- ``shaper_sim_process(**parameters)``: a running shaper_sim, stopped after the test;
- ``mcap_replay(recording, rate=, clock=, topics=, start_offset=)``: a McapReplay of a run
  file or a shipped example's name, stopped after the test;
- ``simulated_run(scenario, markers=False)``: a scenario (YAML file or mapping) simulated
  once per test run, its file's path.
"""

import hashlib
import json
import os
from typing import Any, Callable, Dict, Iterator, List, Mapping, Union

import pytest

from qrm_ros.node.process.ros_isolation import isolate_ros_traffic
from qrm_ros.testing.kit import (example_names, example_recording, McapReplay, RosProcess,
                                 simulate, start_shaper_sim)

__all__ = ['mcap_replay', 'pytest_configure', 'shaper_sim_process', 'simulated_run']

ISOLATE_VARIABLE = 'QRM_ROS_ISOLATE'


def pytest_configure(config: pytest.Config) -> None:
    """Give the run a ROS domain of its own (unless QRM_ROS_ISOLATE=0)."""
    if os.environ.get(ISOLATE_VARIABLE, '1') != '0':
        isolate_ros_traffic(os.environ)


@pytest.fixture
def shaper_sim_process() -> Iterator[Callable[..., RosProcess]]:
    """Start shaper_sim with the given parameters; it is stopped after the test."""
    started: List[RosProcess] = []

    def start(**parameters: Any) -> RosProcess:
        started.append(start_shaper_sim(parameters))
        return started[-1]
    yield start
    for process in started:
        process.stop()


@pytest.fixture
def mcap_replay() -> Iterator[Callable[..., McapReplay]]:
    """Replay a run file (or a shipped example, by name) with mcap_player; stopped after."""
    started: List[McapReplay] = []

    def replay(recording: str, **options: Any) -> McapReplay:
        if not os.path.isfile(recording) and recording in example_names():
            recording = example_recording(recording)
        started.append(McapReplay(recording, **options))
        return started[-1]
    yield replay
    for item in started:
        item.stop()


@pytest.fixture(scope='session')
def simulated_run(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., str]:
    """Simulate a scenario into a run file, once per test run for the same scenario."""
    made: Dict[str, str] = {}
    folder = tmp_path_factory.mktemp('simulated_runs')

    def run(scenario: Union[str, Mapping[str, Any]], markers: bool = False) -> str:
        if isinstance(scenario, str):
            with open(scenario, encoding='utf-8') as handle:
                content: Any = handle.read()
        else:
            content = dict(scenario)
        key_text = json.dumps([content, markers], sort_keys=True)
        key = hashlib.sha256(key_text.encode()).hexdigest()[:16]
        if key not in made:
            made[key] = simulate(scenario, str(folder / f'run_{key}.mcap'), markers=markers)
        return made[key]
    return run
