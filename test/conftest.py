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

Each pytest run takes a ROS domain no other concurrent run on this machine holds (an flock on
a file per domain), and limits discovery to localhost, so parallel runs and other ROS
traffic never cross. Subprocesses inherit the environment.
"""

import fcntl
import os

import pytest

_DOMAIN_RANGE = range(11, 101)
_domain_lock = None


def _claim_domain():
    global _domain_lock
    start = os.getpid() % len(_DOMAIN_RANGE)
    for index in range(len(_DOMAIN_RANGE)):
        domain = _DOMAIN_RANGE[(start + index) % len(_DOMAIN_RANGE)]
        handle = open(f'/tmp/qrm_ros_test_domain_{domain}.lock', 'w')
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _domain_lock = handle
        return domain
    raise RuntimeError('no free ROS domain id for this test run')


def pytest_configure(config):
    os.environ['ROS_DOMAIN_ID'] = str(_claim_domain())
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_STATIC_PEERS', None)
    os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '1')
    config.addinivalue_line('markers', 'slow: longer end-to-end test (-m "not slow" skips)')


@pytest.fixture(scope='session')
def ros_domain_id():
    return int(os.environ['ROS_DOMAIN_ID'])
