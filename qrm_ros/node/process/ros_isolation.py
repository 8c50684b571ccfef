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
ROS traffic isolation for test and benchmark runs on a shared machine.

Each run claims a ROS domain that no other qrm_ros test or benchmark run on this machine
holds (an exclusive lock on a file per domain, held for the life of the process), and keeps
discovery on localhost, so concurrent runs never see each other's nodes.
"""

import fcntl
import os
from typing import List, TextIO

__all__ = ['CLAIMED_VARIABLE', 'claim_ros_domain', 'isolate_ros_traffic']

# Set to the claiming process's id in the environment it isolated.
CLAIMED_VARIABLE = 'QRM_ROS_DOMAIN_CLAIMED_BY'
_held: List[TextIO] = []  # the lock files of the claimed domains, kept open


def claim_ros_domain(domains=range(11, 200)):
    """Return a ROS domain id no other run here holds; the claim lasts while this process does."""
    start = os.getpid() % len(domains)
    for index in range(len(domains)):
        domain = domains[(start + index) % len(domains)]
        handle = open(f'/tmp/qrm_ros_test_domain_{domain}.lock', 'w')
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _held.append(handle)
        return domain
    raise RuntimeError(f'no free ROS domain id in {domains[0]}..{domains[-1]}')


def isolate_ros_traffic(environ=os.environ, domains=range(11, 200)):
    """
    Point environ (default: this process's, inherited by children) at a private domain.

    Once per environment: a second call (a test kit's plugin beside a suite's own set-up)
    keeps the domain this process already claimed for it.
    """
    if environ.get(CLAIMED_VARIABLE) == str(os.getpid()) and 'ROS_DOMAIN_ID' in environ:
        return int(environ['ROS_DOMAIN_ID'])
    environ[CLAIMED_VARIABLE] = str(os.getpid())
    environ['ROS_DOMAIN_ID'] = str(claim_ros_domain(domains))
    environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    environ.pop('ROS_STATIC_PEERS', None)
    return int(environ['ROS_DOMAIN_ID'])
