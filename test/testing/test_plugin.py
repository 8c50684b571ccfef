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
The pytest plugin from the outside: a user's test file, run by pytest in a fresh process.

The file is the example of doc/testing.md (a throwaway subscriber node asserting on the
replayed joint states), found by the installed plugin alone (no conftest); with a wrong
expectation it fails.
"""

import os

from repo_paths import REPO_ROOT

pytest_plugins = ['pytester']

DOC_PAGE = os.path.join(REPO_ROOT, 'doc', 'testing.md')


def _user_test():
    """Return the ten-line test of doc/testing.md (the first python block)."""
    with open(DOC_PAGE, encoding='utf-8') as handle:
        text = handle.read()
    start = text.index('```python\n') + len('```python\n')
    return text[start:text.index('```', start)]


def test_a_user_test_replaying_an_example_passes(pytester):
    pytester.makepyfile(test_my_monitor=_user_test())
    result = pytester.runpytest_subprocess('-q', '-p', 'no:cacheprovider', timeout=300)
    result.assert_outcomes(passed=1)


def test_a_wrong_expectation_fails(pytester):
    source = _user_test()
    assert '== 400' in source
    pytester.makepyfile(test_my_monitor=source.replace('== 400', '== 401'))
    result = pytester.runpytest_subprocess('-q', '-p', 'no:cacheprovider', timeout=300)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(['*assert*400*'])


def test_the_fixtures_are_registered(pytester):
    result = pytester.runpytest_subprocess('--fixtures', '-q', timeout=300)
    result.stdout.fnmatch_lines(['*shaper_sim_process*', '*mcap_replay*', '*simulated_run*'])


FIXTURES_TEST = '''
import rclpy
from sensor_msgs.msg import JointState

from qrm_ros.testing import spin_until, wait_for_topics


def test_a_scenario_is_simulated_once_and_replayed_on_clock(simulated_run, mcap_replay):
    scenario = {'duration': 2.0, 'parameters': {'coupling_offset': 0.01}}
    path = simulated_run(scenario)
    assert simulated_run(dict(scenario)) == path  # made once per test run
    rclpy.init()
    node = rclpy.create_node('listener')
    seen = []
    node.create_subscription(JointState, 'joint_states', seen.append, 100)
    replay = mcap_replay(path, clock=50.0, rate=2.0)
    assert replay.play_to_end(node) == 0
    assert len(seen) == replay.message_count('/joint_states') == 200
    node.destroy_node()
    rclpy.shutdown()


def test_shaper_sim_runs_for_the_test(shaper_sim_process):
    process = shaper_sim_process(coupling_offset=0.005, input_speed=9.0)
    rclpy.init()
    node = rclpy.create_node('listener')
    seen = []
    node.create_subscription(JointState, 'joint_states', seen.append, 100)
    wait_for_topics(node, ['joint_states'], timeout=60.0)
    spin_until(node, lambda: len(seen) > 20, 60.0, 'joint states')
    assert seen[-1].position[4] == 0.005
    assert process.running
    node.destroy_node()
    rclpy.shutdown()
'''


def test_the_other_fixtures_in_a_user_test(pytester):
    pytester.makepyfile(test_fixtures=FIXTURES_TEST)
    result = pytester.runpytest_subprocess('-q', '-p', 'no:cacheprovider', timeout=300)
    result.assert_outcomes(passed=2)
