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
``qrm_main --offline``: the main job's schedule as a scenario, simulated (qrm_simulate).

The live job moves to the next offset once the node reports enough steady stroke pairs; a
scenario is fixed in advance, so each offset is held for the time the actuator takes to get
there (at offset_rate_limit) plus the pairs asked for and SETTLING_PAIRS more (the pair under
way when the offset arrives, and one for the motor's speed to settle). The short-stroke
experiment follows as the live job runs it (main_job_plan), each of its two settings held for
its longest travel (the offset's, the stroke screw's, the held offset's) and the same pairs.
The file is the one the live job records (the recorder's topics and the linkage markers).
"""

import argparse
import math
import os
from dataclasses import replace
from typing import Any, Dict, List

from qrm_ros.cli.main_job_plan import short_stroke_plan, start_up_parameters, STROKE_RATE_LIMIT
from qrm_ros.cli.qrm_simulate import simulate
from qrm_ros.core import kinematics as kin
from qrm_ros.core.kinematics.geometry import crank_radius_for_stroke
from qrm_ros.core.design.time_ratio_hold import hold_time_ratio
from qrm_ros.node.main_job.main_job_conductor import Interrupted, MainJobError
from qrm_ros.node.process.ros_process import StopRequest
from qrm_ros.node.offline.scenario import Scenario, scenario_from_mapping, ScenarioError
from qrm_ros.recording.mcap_run_file import RecorderError

__all__ = ['SETTLING_PAIRS', 'offline_scenario', 'simulate_schedule']

# Stroke pairs held at each offset beyond those asked for (see the module docstring).
SETTLING_PAIRS = 2


def offline_scenario(options: argparse.Namespace) -> Scenario:
    """Return the scenario of the main job's options (offsets, speed, loads, drive, rates)."""
    offsets = [value / 1e3 for value in options.offsets_mm]
    period = 2 * math.pi / abs(options.input_speed)
    hold = (options.pairs + SETTLING_PAIRS) * period
    events: List[Dict[str, Any]] = []
    at = hold
    for before, offset in zip(offsets, offsets[1:]):
        events.append({'at': at, 'set': {'coupling_offset': offset}})
        at += abs(offset - before) / options.offset_rate_limit + hold
    if options.short_stroke_mm:
        at = _short_stroke_events(options, offsets[-1], at, hold, events)
    parameters = start_up_parameters(options)
    return scenario_from_mapping({'parameters': parameters, 'duration': at, 'events': events})


def _short_stroke_events(options: argparse.Namespace, last_offset: float, at: float,
                         hold: float, events: List[Dict[str, Any]]) -> float:
    """Add the short-stroke experiment's two settings from time at; return its end (s)."""
    plan = short_stroke_plan(options.short_stroke_mm, options.cutting_length)
    long_stroke = kin.Geometry.paper()
    events.append({'at': at, 'set': {'coupling_offset': 0.0, 'cutting_length': plan.workpiece,
                                     'stroke_length': plan.stroke}})
    at += max(abs(last_offset) / options.offset_rate_limit,
              abs(float(long_stroke.ram_stroke) - plan.stroke) / STROKE_RATE_LIMIT) + hold
    short = replace(long_stroke, crank_radius=float(crank_radius_for_stroke(
        plan.stroke, long_stroke.pivot_distance, long_stroke.ram_height)))
    held = hold_time_ratio(short, plan.time_ratio).offset
    events.append({'at': at, 'set': {'time_ratio_target': plan.time_ratio}})
    return at + abs(held) / options.offset_rate_limit + hold


def simulate_schedule(options: argparse.Namespace, folder: str, stop: StopRequest) -> str:
    """Simulate the schedule into folder/run.mcap; return its path (MainJobError if refused)."""
    recording = os.path.join(folder, 'run.mcap')
    try:
        scenario = offline_scenario(options)
        print(f'qrm_main: simulating {scenario.duration:.1f} s of the schedule offline',
              flush=True)
        summary = simulate(scenario, recording, markers=True, stop=stop)
    except (ScenarioError, RecorderError, ValueError) as error:
        raise MainJobError(f'the offline run was refused: {error}') from None
    if summary.stopped:
        assert stop.signal_number is not None
        raise Interrupted(stop.signal_number, folder)
    return recording
