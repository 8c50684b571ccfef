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
The ``shaper_sim`` command: runs the shaper_sim node (qrm_ros.node.shaper_sim).

ROS arguments after ``--ros-args`` (``-p name:=value``, ``--params-file``). Exit codes
(qrm_ros.cli.exit_codes): 0 stopped by Ctrl-C or SIGTERM, 2 bad start-up arguments or
parameters (one line on stderr says which and why).
"""

import sys
from typing import List, Optional

from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_OK
from qrm_ros.core.names import SIM_NODE_NAME
from qrm_ros.node.ros_process import (executor_kind, init_rclpy, new_executor, RCLError,
                                      rcl_error_text, spin_until_stopped, StopRequest)
from qrm_ros.node.shaper_sim import ShaperSimNode
import rclpy

__all__ = ['main']


def main(argv: Optional[List[str]] = None) -> int:
    """Run the node until Ctrl-C or SIGTERM; exit 2 on bad start-up arguments or parameters."""
    try:
        init_rclpy(argv)  # None: rclpy reads sys.argv
    except RCLError as error:  # a malformed -p or params file, said by rcl
        print(f'{SIM_NODE_NAME}: cannot start: {rcl_error_text(error)}', file=sys.stderr)
        return EXIT_BAD_INPUT
    node = executor = None
    try:
        with StopRequest() as stop:
            try:
                kind = executor_kind()  # QRM_ROS_EXECUTOR: events (default) or single
                node = ShaperSimNode()
            except ValueError as error:
                # Say which start-up value and why, no traceback (KinematicsError included).
                print(f'{SIM_NODE_NAME}: cannot start: {error}', file=sys.stderr)
                return EXIT_BAD_INPUT
            executor = new_executor(kind)
            executor.add_node(node)
            spin_until_stopped(executor, stop)
    finally:
        if executor is not None:
            executor.shutdown()  # lets go of the node's entities before they are destroyed
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
