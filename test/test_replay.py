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
Replay of the golden logs in test/data (recorded by the real node and recorder).

Each log is re-derived from its own content:
(a) from the logged input angle, input speed, offset and offset rate at every stamp, the
    kinematics core reproduces the logged flywheel, lever and ram states (and the twist) to
    1e-12;
(b) stepping ShaperStepper from the first logged sample through the logged parameter changes
    (/parameter_events, stamped by the node's clock between two ticks) at the logged stamps
    reproduces the logged input angle, input speed and offset bit for bit.
And the offline analysis of each log finds exactly the commanded settings and measures TR and
SR within the stroke finder's bound of the closed form.
A change to the physics, the stepping or the analysis that alters their output fails here.
"""

import glob
import json
import math
import os

import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores

from qrm_ros import analysis
from qrm_ros import kinematics as kin
from qrm_ros.bag_reader import open_run
from qrm_ros.names import JOINT_NAMES
from qrm_ros.stepping import ShaperStepper

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'data')
LOGS = sorted(glob.glob(os.path.join(DATA, '*.mcap')))
JOINTS = list(JOINT_NAMES)
# The settings make_golden_logs.py commanded: (offset m, input speed rad/s) per log.
COMMANDED = {
    'steady_positive_offset': [(0.010, 2 * math.pi)],
    'steady_negative_offset': [(-0.010, 2 * math.pi)],
    'offset_and_speed_change': [(0.0, 2 * math.pi), (0.012, 2 * math.pi), (0.012, 9.0),
                                (-0.008, 2 * math.pi)],
}
STORE = get_typestore(Stores.ROS2_JAZZY)


def _ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class Log:
    def __init__(self, path):
        run = open_run(path)
        assert not run.truncated
        self.geometry = kin.Geometry(**{k: float(v) for k, v in
                                        run.metadata['qrm_ros.geometry'].items()})
        self.parameters = {k: json.loads(v) for k, v in
                           run.metadata['qrm_ros.parameters'].items()}
        stamps, positions, velocities, twists, self.events = [], [], [], {}, []
        for recorded in run.messages():
            message = STORE.deserialize_cdr(recorded.data, recorded.schema_name)
            topic = recorded.topic
            if topic == '/joint_states':
                assert list(message.name) == JOINTS
                stamps.append(_ns(message.header.stamp))
                positions.append(message.position)
                velocities.append(message.velocity)
            elif topic == '/ram/twist':
                twists[_ns(message.header.stamp)] = message.twist.linear.x
            elif topic == '/parameter_events' and message.node == '/shaper_sim':
                for parameter in message.changed_parameters:
                    self.events.append((_ns(message.stamp), parameter.name,
                                        parameter.value.double_value))
        order = np.argsort(stamps, kind='stable')
        self.stamps = [stamps[i] for i in order]
        self.position = np.array(positions)[order]
        self.velocity = np.array(velocities)[order]
        self.twists = twists
        self.events.sort()


@pytest.fixture(scope='module', params=LOGS, ids=lambda p: os.path.basename(p)[:-5])
def log(request):
    return Log(request.param)


def test_the_golden_logs_are_there_and_small():
    assert {os.path.basename(p)[:-5] for p in LOGS} == set(COMMANDED)
    for path in LOGS:
        assert os.path.getsize(path) <= 1_000_000


def test_core_reproduces_every_logged_state(log):
    angle, offset = log.position[:, 0], log.position[:, 4]
    speed, offset_rate = log.velocity[:, 0], log.velocity[:, 4]
    state = kin.state(log.geometry, offset, angle, speed, 0.0, offset_rate)
    wrapped = np.angle(np.exp(1j * (state.flywheel_angle - log.position[:, 1])))
    assert np.max(np.abs(wrapped)) < 1e-12
    np.testing.assert_allclose(state.flywheel_speed, log.velocity[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.lever_angle, log.position[:, 2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.lever_speed, log.velocity[:, 2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.ram_position, log.position[:, 3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.ram_velocity, log.velocity[:, 3], rtol=0, atol=1e-12)
    matched = [(log.twists[s], v) for s, v in zip(log.stamps, log.velocity[:, 3])
               if s in log.twists]
    assert len(matched) >= len(log.stamps) - 2
    assert all(twist == joint for twist, joint in matched)


def test_stepper_replays_the_logged_trajectory_bit_for_bit(log):
    parameters = dict(log.parameters)
    events = list(log.events)
    while events and events[0][0] <= log.stamps[0]:  # commands in force at the first sample
        _, name, value = events.pop(0)
        parameters[name] = value
    stepper = ShaperStepper(log.geometry, parameters['input_speed'],
                            parameters['coupling_offset'],
                            parameters['input_acceleration_limit'],
                            parameters['offset_rate_limit'])
    stepper.restore(log.stamps[0], log.position[0, 0], log.velocity[0, 0], log.position[0, 4])
    stepper.set_speed_command(parameters['input_speed'])
    stepper.set_offset_command(parameters['coupling_offset'])
    applied = 0
    for k in range(1, len(log.stamps)):
        # A command stamped between two ticks took effect from the earlier tick.
        while events and events[0][0] < log.stamps[k]:
            _, name, value = events.pop(0)
            applied += 1
            if name == 'input_speed':
                stepper.set_speed_command(value)
            elif name == 'coupling_offset':
                stepper.set_offset_command(value)
            elif name == 'input_acceleration_limit':
                stepper.set_limits(input_acceleration_limit=value)
            elif name == 'offset_rate_limit':
                stepper.set_limits(offset_rate_limit=value)
        stepper.integrate_to(log.stamps[k])
        got = (stepper.input_angle, stepper.input_speed, stepper.offset, stepper.offset_rate)
        logged = (log.position[k, 0], log.velocity[k, 0], log.position[k, 4],
                  log.velocity[k, 4])
        assert got == logged, f'sample {k} at {log.stamps[k]} ns: replay {got} != log {logged}'
    assert applied == len(log.events) - sum(1 for e in log.events if e[0] <= log.stamps[0])


def test_analysis_finds_the_commanded_settings_and_theory(log, request):
    name = os.path.basename(request.node.callspec.params['log'])[:-5]
    path = os.path.join(DATA, name + '.mcap')
    result = analysis.analyse(analysis.read_recording(path))
    assert [(row['offset'], row['input_speed']) for row in result.rows] == COMMANDED[name]
    for row in result.rows:
        assert row['stroke_pairs'] >= 2
        tolerance = (abs(row['input_speed']) * 0.01) ** 3  # derived in test_strokes
        for key in ('time_ratio', 'speed_ratio', 'peak_speed_ratio'):
            assert abs(row[f'{key}_relative_error']) < tolerance, (key, row)
        assert row['time_ratio_theory'] == pytest.approx(
            kin.time_ratio_rk4(log.geometry, row['offset']), rel=1e-9)
