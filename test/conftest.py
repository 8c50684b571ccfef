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
Test-session set-up shared by every test module.

Each pytest run takes a ROS domain no other concurrent run on this machine holds and limits
discovery to localhost (qrm_ros.node.process.ros_isolation), so parallel runs and other ROS traffic
never cross. Subprocesses inherit the environment.
"""

import os

import pytest
import rclpy
from rclpy.context import Context

from qrm_ros.node.process.ros_isolation import isolate_ros_traffic


def pytest_configure(config):
    isolate_ros_traffic(os.environ)
    os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '1')
    config.addinivalue_line('markers', 'slow: longer end-to-end test (-m "not slow" skips)')
    config.addinivalue_line('markers', 'bits: compares results bit for bit on the reference '
                            'machines (doc/reproducibility.md); test_reproducibility.py runs '
                            'these again under other math kernels')


@pytest.fixture(scope='session')
def ros_domain_id():
    return int(os.environ['ROS_DOMAIN_ID'])


@pytest.fixture(scope='module')
def context():
    """Give the test module an rclpy context of its own."""
    context = Context()
    rclpy.init(context=context)
    yield context
    rclpy.shutdown(context=context)


@pytest.fixture
def harness(context):
    made = []

    def make(**kwargs):
        from shaper_harness import Harness
        made.append(Harness(context, **kwargs))
        return made[-1]
    yield make
    for item in made:
        item.close()


@pytest.fixture(scope='module')
def run_with_efforts(tmp_path_factory):
    """Write a synthetic run whose joint states carry made-up efforts (animation tests)."""
    from synthetic_run import EFFORTS_SCHEDULE, made_up_efforts, write_run
    path = tmp_path_factory.mktemp('runs') / 'efforts.mcap'
    write_run(path, effort=made_up_efforts, **EFFORTS_SCHEDULE)
    return path
