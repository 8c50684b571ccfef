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
How this package's ROS processes start and stop: clean stops on Ctrl-C and SIGTERM.

rclpy's own signal handler shuts the context down from another thread at any moment; an
executor that is between its `context.ok()` check and building its wait set then raises
`RCLError: ... the given context is not valid` (a traceback on a plain SIGTERM, about one
stop in three here). So the processes init rclpy without its handlers, and a signal only
records a stop request: the spin loop sees it between callbacks, finishes what it is doing,
and the process shuts rclpy down itself, in order.

Which executor spins them: rclpy's EventsExecutor by default (experimental in Jazzy, but it
takes half the CPU of the SingleThreadedExecutor at 1 kHz: it does not rebuild a wait set at
every wake-up). QRM_ROS_EXECUTOR=single falls back to the SingleThreadedExecutor. What the
EventsExecutor of rclpy 7.1 does, as checked by test_executor.py: timers on simulated time
(/clock steps, pauses, jumps both ways), cancel and reset, services, parameter services,
clients, QoS events; it leaves SIGINT/SIGTERM to Python (so StopRequest works as with the
other executor). It refuses nodes with guard conditions (RuntimeError "Guard conditions not
supported"); this package's nodes have none. And it calls a subscription callback that takes
the message info with one argument, the (message, info) pair, where the other executors pass
two (a two-parameter callback then fails: "SystemError: null argument to internal routine");
MESSAGE_INFO_SIGNATURE and message_and_info make a callback that works on both.

The long-running commands (shaper_sim, mcap_recorder, qrm_bridge) start and stop alike:
start_rclpy refuses a malformed command line in one line, and run_node makes the node, spins
it until a stop signal, and tears everything down in order, turning the errors the command
names into a one-line message and its exit code.
"""

import gc
import inspect
import os
import re
import signal
from typing import Callable, List, Mapping, Optional, Sequence, Tuple, Type, TypeVar, Union

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args, try_shutdown

__all__ = ['EXECUTOR_VARIABLE', 'EXECUTORS', 'ExecutorChoiceError', 'IDLE_WAKEUP',
           'MESSAGE_INFO_SIGNATURE', 'RCLError', 'StopRequest', 'executor_kind', 'init_rclpy',
           'message_and_info', 'new_executor', 'rcl_error_text', 'run_node', 'spin_until_stopped',
           'start_rclpy']

RCLError = _rclpy.RCLError  # rcl failures (bad arguments, invalid context); as rclpy.action
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
# Longest wait for a stop request when no callback is due (e.g. use_sim_time, no /clock).
IDLE_WAKEUP = 0.1  # s
# The environment variable that chooses the executor, and its values (the first: default).
EXECUTOR_VARIABLE = 'QRM_ROS_EXECUTOR'
EXECUTORS = ('events', 'single')
# The signature rclpy reads to pass a subscription callback the message info: set it as the
# __signature__ of a callback that takes *arguments and unpacks them with message_and_info.
MESSAGE_INFO_SIGNATURE = inspect.Signature(
    [inspect.Parameter(name, inspect.Parameter.POSITIONAL_ONLY) for name in ('message', 'info')])


class ExecutorChoiceError(ValueError):
    """QRM_ROS_EXECUTOR names no executor of this package."""


def init_rclpy(args=None, context=None):
    """rclpy.init without rclpy's signal handlers: StopRequest handles the stop signals."""
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)


def rcl_error_text(error):
    """One line from an RCLError, without rcl's source locations (`, at /project/...c:239`)."""
    return re.sub(r', at /\S+:\d+', '', str(error)).strip()


class StopRequest:
    """
    While entered, SIGINT and SIGTERM only record that a stop was asked for.

    Truthy once a signal came; `signal_number` says which. The handlers before are restored
    on exit.
    """

    def __init__(self, signals=STOP_SIGNALS):
        self._signals = signals
        self._previous = {}
        self.signal_number = None

    def _on_signal(self, signal_number, frame):
        del frame
        if self.signal_number is None:
            self.signal_number = signal_number

    def __bool__(self):
        return self.signal_number is not None

    def __enter__(self):
        self._previous = {number: signal.signal(number, self._on_signal)
                          for number in self._signals}
        return self

    def __exit__(self, *exc_info):
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        return False


def spin_until_stopped(executor, stop, idle_wakeup=IDLE_WAKEUP):
    """
    Run the executor's callbacks until the stop request (or the context) ends it.

    What exists before the spinning (modules, nodes) lives till the end: gc.freeze() takes
    it out of the garbage collector's view, so a full collection scans only what the run
    allocated (with numpy, scipy and rclpy loaded one took 18-29 ms inside a node's tick).
    """
    gc.collect()
    gc.freeze()
    while not stop and executor.context.ok():
        try:
            executor.spin_once(timeout_sec=idle_wakeup)
        except ExternalShutdownException:  # the context was shut down from another thread
            return


def executor_kind(environ=None):
    """Return the executor QRM_ROS_EXECUTOR asks for ('events' when unset or empty)."""
    environ = os.environ if environ is None else environ
    kind = environ.get(EXECUTOR_VARIABLE, '').strip().lower() or EXECUTORS[0]
    if kind not in EXECUTORS:
        raise ExecutorChoiceError(
            f'{EXECUTOR_VARIABLE}={environ[EXECUTOR_VARIABLE]!r} is not an executor: allowed '
            f'{", ".join(EXECUTORS)} (unset: {EXECUTORS[0]})')
    return kind


def new_executor(kind=None, context=None):
    """Make the executor `kind` ('events' or 'single'; None: as QRM_ROS_EXECUTOR says)."""
    kind = executor_kind() if kind is None else kind
    if kind == 'events':
        from rclpy.experimental.events_executor import EventsExecutor
        return EventsExecutor(context=context)
    if kind == 'single':
        return SingleThreadedExecutor(context=context)
    raise ExecutorChoiceError(f'executor {kind!r}: allowed {", ".join(EXECUTORS)}')


def message_and_info(arguments):
    """Return (message, info) from a MESSAGE_INFO_SIGNATURE callback's arguments, any executor."""
    return arguments if len(arguments) == 2 else arguments[0]


def start_rclpy(argv: Optional[Sequence[str]], say: Callable[[str], None]) -> bool:
    """init_rclpy(argv) (None: sys.argv); on a malformed -p or params file say rcl's reason."""
    try:
        init_rclpy(argv)
    except RCLError as error:
        say(rcl_error_text(error))
        return False
    return True


def own_arguments_of(command_line: Sequence[str], say: Callable[[str], None]
                     ) -> Optional[List[str]]:
    """Return a command's own arguments (ROS's and the program name removed), or None.

    None: rcl refused the ROS arguments (a malformed -p, say); its reason has been said.
    """
    try:
        return remove_ros_args(list(command_line))[1:]
    except RCLError as error:
        say(rcl_error_text(error))
        return None


MadeNode = TypeVar('MadeNode', bound=Node)
Refusals = Mapping[Union[Type[BaseException], Tuple[Type[BaseException], ...]], int]


def run_node(make_node: Callable[[], MadeNode], say: Callable[[str], None],
             refusals: Refusals, *, on_ready: Optional[Callable[[MadeNode], None]] = None,
             on_stop: Optional[Callable[[MadeNode, object], None]] = None,
             on_close: Optional[Callable[[MadeNode], None]] = None) -> Optional[int]:
    """
    Make the node (rclpy started), spin it until Ctrl-C or SIGTERM, tear it all down.

    refusals: exception type(s) -> exit code, the first that matches wins; such an error,
    from the executor's choice (QRM_ROS_EXECUTOR), the node's making, its spinning or on_stop,
    is said in one line and its code returned. None when the node ran and stopped cleanly.
    on_ready(node) runs once the node is made, on_stop(node, executor) after the stop
    request (still spinnable: e.g. to drain), on_close(node) before the node is destroyed.
    rclpy is shut down in any case.
    """
    refused = tuple(kind for kinds in refusals
                    for kind in (kinds if isinstance(kinds, tuple) else (kinds,)))
    node: Optional[MadeNode] = None
    executor = None
    try:
        with StopRequest() as stop:
            kind = executor_kind()  # QRM_ROS_EXECUTOR: events (default) or single
            node = make_node()
            if on_ready is not None:
                on_ready(node)
            executor = new_executor(kind)
            executor.add_node(node)
            spin_until_stopped(executor, stop)
            if on_stop is not None:
                on_stop(node, executor)
    except refused as error:
        say(str(error))
        return next(code for kinds, code in refusals.items() if isinstance(error, kinds))
    finally:
        if executor is not None:
            executor.shutdown()  # lets go of the node's entities before they are destroyed
        if node is not None:
            if on_close is not None:
                on_close(node)
            node.destroy_node()
        try_shutdown()
    return None
