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
The ``qrm_bridge`` command: the ROS 2 graph, live, in the Foxglove app (node.bridge).

``qrm_bridge`` serves every topic; ``--topics joint_states linkage_markers`` only those. It
listens on the loopback address unless ``--address`` says otherwise, and prints the address
to open in the app (Open connection, Foxglove WebSocket). ROS arguments go after
``--ros-args``.

Exit codes (qrm_ros.cli.exit_codes): 0 stopped by Ctrl-C or SIGTERM, 1 the server cannot
start (the port is taken, the address is not this machine's), 2 bad options.
"""

import argparse
import sys
from typing import List, Optional

from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK
from qrm_ros.core.common.names import BRIDGE_NODE_NAME, BRIDGE_SERVING_PREFIX
from qrm_ros.node.bridge.foxglove_bridge import (BridgeNode, BridgeSettings, DEFAULT_ADDRESS,
                                                 DEFAULT_CLIENT_QUEUE, DEFAULT_PORT,
                                                 DEFAULT_SEND_PERIOD)
from qrm_ros.node.process.ros_process import (ExecutorChoiceError, own_arguments_of, run_node,
                                              start_rclpy)

__all__ = ['main']

PORT_RANGE = (0, 65535)
CLIENT_QUEUE_RANGE = (1, 1_000_000)
SEND_PERIOD_RANGE = (0.0, 1.0)  # s


class CannotServe(RuntimeError):
    """The server cannot start: the port is taken, or the address is not this machine's."""


def _parser():
    parser = argparse.ArgumentParser(
        prog=BRIDGE_NODE_NAME,
        description='Serve the ROS 2 graph to the Foxglove app over the Foxglove WebSocket '
                    'protocol: topics, parameters, services and publishing from the app.',
        epilog='Exit codes: 0 stopped by Ctrl-C or SIGTERM, 1 the server cannot start, 2 bad '
               'options. ROS arguments go after --ros-args.')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC',
                        help='serve only these topics (default: every topic of the graph)')
    parser.add_argument('--address', default=DEFAULT_ADDRESS,
                        help=f'address to listen on (default: {DEFAULT_ADDRESS}, this machine '
                             'only; 0.0.0.0 opens it to the network)')
    parser.add_argument('--port', type=int, default=DEFAULT_PORT,
                        help=f'TCP port, {PORT_RANGE[0]}-{PORT_RANGE[1]} (default: '
                             f'{DEFAULT_PORT}; 0: any free port, printed)')
    parser.add_argument('--client-queue', type=int, default=DEFAULT_CLIENT_QUEUE,
                        help='messages a client may fall behind before its oldest are dropped, '
                             f'{CLIENT_QUEUE_RANGE[0]}-{CLIENT_QUEUE_RANGE[1]} (default: '
                             f'{DEFAULT_CLIENT_QUEUE})')
    parser.add_argument('--send-period', type=float, default=DEFAULT_SEND_PERIOD,
                        metavar='SECONDS',
                        help='how often the messages gathered from ROS are handed to the '
                             f'server, {SEND_PERIOD_RANGE[0]:g}-{SEND_PERIOD_RANGE[1]:g} s '
                             f'(default: {DEFAULT_SEND_PERIOD:g} s; 0: each as it arrives, '
                             'at several times the CPU)')
    return parser


def _checked(parser, options):
    limits = (('--port', options.port, PORT_RANGE),
              ('--client-queue', options.client_queue, CLIENT_QUEUE_RANGE))
    for name, value, (low, high) in limits:
        if not low <= value <= high:
            parser.error(f'{name} {value} is outside {low}-{high}')  # exit code 2
    low, high = SEND_PERIOD_RANGE
    if not low <= options.send_period <= high:  # NaN too
        parser.error(f'--send-period {options.send_period:g} s is outside {low:g}-{high:g} s')
    if not options.address.strip():
        parser.error('--address is empty')
    return BridgeSettings(options.address.strip(), options.port, options.topics,
                          options.client_queue, options.send_period)


def _error(text):
    print(f'{BRIDGE_NODE_NAME}: error: {text}', file=sys.stderr, flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    """Serve until Ctrl-C or SIGTERM; argv is the whole command line (None: sys.argv)."""
    command_line = sys.argv if argv is None else argv
    own_arguments = own_arguments_of(command_line, _error)
    if own_arguments is None:
        return EXIT_BAD_INPUT
    parser = _parser()
    settings = _checked(parser, parser.parse_args(own_arguments))
    if not start_rclpy(command_line, _error):
        return EXIT_BAD_INPUT

    def serve():
        try:
            return BridgeNode(settings)
        except RuntimeError as error:  # the SDK cannot bind (port taken, bad address)
            raise CannotServe(f'cannot serve on {settings.address} port {settings.port}: '
                              f'{error}') from None

    def say_address(node):
        print(f'{BRIDGE_SERVING_PREFIX}{node.address} (in the Foxglove app: Open '
              'connection, Foxglove WebSocket, this address)', flush=True)
    code = run_node(serve, _error, {ExecutorChoiceError: EXIT_BAD_INPUT,
                                    CannotServe: EXIT_FAILURE},
                    on_ready=say_address, on_close=BridgeNode.close)
    return EXIT_OK if code is None else code


if __name__ == '__main__':
    sys.exit(main())
