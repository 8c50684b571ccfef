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
The ``shaper_sim`` command: runs the shaper_sim node (qrm_ros.node.shaper_sim.shaper_sim).

ROS arguments after ``--ros-args`` (``-p name:=value``, ``--params-file``). Exit codes
(qrm_ros.cli.exit_codes): 0 stopped by Ctrl-C or SIGTERM, 2 bad start-up arguments or
parameters (one line on stderr says which and why).
"""

import sys
from typing import List, Optional

from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_OK
from qrm_ros.core.common.names import SIM_NODE_NAME
from qrm_ros.node.process.ros_process import run_node, start_rclpy
from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode

__all__ = ['main']


def _say(text):
    print(f'{SIM_NODE_NAME}: cannot start: {text}', file=sys.stderr, flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    """Run the node until Ctrl-C or SIGTERM; exit 2 on bad start-up arguments or parameters."""
    if not start_rclpy(argv, _say):  # None: rclpy reads sys.argv
        return EXIT_BAD_INPUT
    # Which start-up value and why, no traceback (KinematicsError and a bad executor included).
    code = run_node(ShaperSimNode, _say, {ValueError: EXIT_BAD_INPUT})
    return EXIT_OK if code is None else code


if __name__ == '__main__':
    sys.exit(main())
