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
"""The test kit's helpers: the shipped examples are what their scenarios give; the processes."""

import os

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from qrm_ros.recording.bag_reader import open_run
from qrm_ros.testing import (assert_runs_match, EXAMPLES_FOLDER, example_names, example_recording,
                             example_scenario, OTHER_MACHINE_RELATIVE, reference_math, simulate,
                             start_shaper_sim, wait_for_topics)

EXAMPLES = ['motor_cutting', 'offset_step', 'steady_offset']


def _states(path):
    return [(m.header.stamp.sec, m.header.stamp.nanosec, m.position.tobytes(),
             m.velocity.tobytes(), m.effort.tobytes())
            for m in (deserialize_message(message.data, JointState)
                      for message in open_run(path).messages('/joint_states'))]


def test_the_examples_are_few_and_small():
    assert example_names() == EXAMPLES
    total = sum(os.path.getsize(os.path.join(EXAMPLES_FOLDER, name))
                for name in os.listdir(EXAMPLES_FOLDER))
    assert total < 400_000
    with pytest.raises(FileNotFoundError, match='the examples are motor_cutting'):
        example_recording('nothing')


def _joint_values(path):
    messages = [deserialize_message(message.data, JointState)
                for message in open_run(path).messages('/joint_states')]
    return ([(m.header.stamp.sec, m.header.stamp.nanosec) for m in messages],
            np.array([np.concatenate([m.position, m.velocity, m.effort]) for m in messages]))


@pytest.mark.bits
@pytest.mark.parametrize('name', EXAMPLES)
def test_each_example_is_what_its_scenario_gives(tmp_path, name):
    # The shipped run is the simulator's of the shipped scenario: not stale, every bit of
    # every topic on the reference machines, the motion within its bound elsewhere.
    made = simulate(example_scenario(name), str(tmp_path / 'again.mcap'))
    if reference_math():
        assert_runs_match(made, example_recording(name))
        assert _states(made) == _states(example_recording(name))
    else:
        stamps, values = _joint_values(made)
        shipped_stamps, shipped = _joint_values(example_recording(name))
        assert stamps == shipped_stamps
        scale = np.max(np.abs(shipped), axis=0)
        assert np.all(np.abs(values - shipped) <= OTHER_MACHINE_RELATIVE * scale)
    shipped = open_run(example_recording(name))
    assert shipped.message_count('/joint_states') >= 400
    assert not shipped.problem and shipped.counted


def test_simulate_says_why_a_scenario_is_refused(tmp_path):
    with pytest.raises(RuntimeError, match='coupling_offset = 0.05 refused'):
        simulate({'duration': 1.0, 'parameters': {'coupling_offset': 0.05}},
                 str(tmp_path / 'refused.mcap'))
    assert not (tmp_path / 'refused.mcap').exists()


def test_shaper_sim_runs_for_a_test_and_stops_cleanly(context):
    node = Node('kit_probe', context=context)
    try:
        with start_shaper_sim({'coupling_offset': 0.01, 'frame_id': 'base'}) as process:
            wait_for_topics(node, ['joint_states', 'ram/twist'], timeout=60.0)
            assert process.running
        assert process.process.returncode == 0
    finally:
        node.destroy_node()
