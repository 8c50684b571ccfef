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
The test kit: this package's commands run for the length of a test, and example runs.

Each helper starts a command of the package (shaper_sim, mcap_player, qrm_simulate) as a
process of its own, in the environment of the test (its ROS domain: the pytest plugin gives
each test run one no other run on the machine holds), and stops it with SIGINT, as a user
would, killing it only if it does not stop. The test's own node is the one that waits: for
topics, for the player's publishers, for the messages to arrive.
"""

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from typing import Any, Callable, Iterator, List, Mapping, Optional, Sequence, Union

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger
import yaml

from qrm_ros.core.common.names import absolute_topic
from qrm_ros.node.player.mcap_player import PLAYER_NODE_NAME
from qrm_ros.recording.bag_reader import open_run, Run

__all__ = ['EXAMPLES_FOLDER', 'McapReplay', 'RosProcess', 'example_names', 'example_recording',
           'example_scenario', 'simulate', 'spin_until', 'start_shaper_sim', 'wait_for_topics']

# The example runs and their scenarios, installed with the package.
EXAMPLES_FOLDER = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'examples')
# s a process is given to stop after SIGINT before it is killed.
STOP_TIMEOUT = 30.0
# s the test's node is spun at a time while waiting.
IDLE_SPIN = 0.05
# Spins after the last message, for callbacks of the node's own.
IDLE_SPINS = 10


def example_names() -> List[str]:
    """Return the names of the example runs shipped with the package."""
    return sorted(name[:-len('.mcap')] for name in os.listdir(EXAMPLES_FOLDER)
                  if name.endswith('.mcap'))


def _example_file(name: str, suffix: str, what: str) -> str:
    """Return the path of a shipped example's file; FileNotFoundError names the examples."""
    path = os.path.join(EXAMPLES_FOLDER, name + suffix)
    if not os.path.isfile(path):
        raise FileNotFoundError(f'no example {what} {name!r}: the examples are '
                                f'{", ".join(example_names())}')
    return path


def example_recording(name: str) -> str:
    """Return the path of a shipped example run ('steady_offset', ...; example_names())."""
    return _example_file(name, '.mcap', 'run')


def example_scenario(name: str) -> str:
    """Return the path of the scenario (YAML) a shipped example run was simulated from."""
    return _example_file(name, '.yaml', 'scenario')


def _command(name: str) -> str:
    """Return a console script of the package: beside this Python first, then on PATH."""
    beside = os.path.join(os.path.dirname(sys.executable), name)
    if os.access(beside, os.X_OK):
        return beside
    found = shutil.which(name)
    if found is None:
        raise FileNotFoundError(f'command {name} not found beside {sys.executable} nor on '
                                'PATH: is qrm_ros installed in this environment?')
    return found


def _parameter_text(value: Any) -> str:
    """Write a parameter value as ``-p name:=value`` reads it (YAML)."""
    if isinstance(value, float):
        return repr(value)
    text = yaml.safe_dump(value, default_flow_style=True).strip()
    return text[:-len('...')].strip() if text.endswith('...') else text


class RosProcess:
    """A command of the package running in the background; stop() ends it cleanly."""

    def __init__(self, command: Sequence[str], environ: Optional[Mapping[str, str]] = None):
        self.command = list(command)
        self.process = subprocess.Popen(
            self.command, env=dict(environ) if environ is not None else None,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    @property
    def running(self) -> bool:
        """Whether the process is still running."""
        return self.process.poll() is None

    def wait(self, timeout: Optional[float] = None) -> int:
        """Wait for the process to end; return its exit code (TimeoutExpired after timeout)."""
        return self.process.wait(timeout)

    def stop(self, timeout: float = STOP_TIMEOUT) -> int:
        """Send SIGINT, wait, kill it after timeout s; return its exit code."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        return self.process.returncode

    def output(self) -> str:
        """Return what the (ended) process wrote on stderr: its log and warnings."""
        if self.process.poll() is None:
            return ''
        assert self.process.stderr is not None
        return self.process.stderr.read()

    def __enter__(self) -> 'RosProcess':
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.stop()


def _start_command(name: str, arguments: Sequence[str] = (),
                   environ: Optional[Mapping[str, str]] = None) -> RosProcess:
    """Start a command of the package (found as _command finds it) with these arguments."""
    return RosProcess([_command(name), *arguments], environ)


def start_shaper_sim(parameters: Optional[Mapping[str, Any]] = None,
                     environ: Optional[Mapping[str, str]] = None) -> RosProcess:
    """Start shaper_sim with start-up parameters (e.g. {'coupling_offset': 0.01})."""
    arguments = ['--ros-args']
    for name, value in (parameters or {}).items():
        arguments += ['-p', f'{name}:={_parameter_text(value)}']
    return _start_command('shaper_sim', arguments, environ)


@contextlib.contextmanager
def _lent_executor(node: Node) -> Iterator[SingleThreadedExecutor]:
    """Lend the node an executor of its own context, for the while (nothing else spun)."""
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        yield executor
    finally:
        executor.remove_node(node)
        executor.shutdown()


def spin_until(node: Node, predicate: Callable[[], bool], timeout: float = 30.0,
               what: str = 'a condition') -> None:
    """
    Spin the test's node until predicate() is true; TimeoutError naming what after timeout.

    The node is spun by an executor of its own context for the while (not spun elsewhere).
    """
    deadline = time.monotonic() + timeout
    with _lent_executor(node) as executor:
        while not predicate():
            if time.monotonic() > deadline:
                raise TimeoutError(f'timed out after {timeout:g} s waiting for {what}')
            executor.spin_once(timeout_sec=IDLE_SPIN)


def _spin_ready(node: Node, spins: int) -> None:
    """Run up to `spins` of the node's ready callbacks, one per spin, without waiting."""
    with _lent_executor(node) as executor:
        for _ in range(spins):
            executor.spin_once(timeout_sec=0.0)


def wait_for_topics(node: Node, topics: Sequence[str], timeout: float = 30.0) -> None:
    """Spin the test's node until each topic has a publisher (names as the node resolves them)."""
    wanted = [node.resolve_topic_name(topic) for topic in topics]
    spin_until(node, lambda: all(node.count_publishers(topic) > 0 for topic in wanted),
               timeout, 'publishers on ' + ', '.join(wanted))


class McapReplay:
    """
    A recording played back by mcap_player, paused until the test's node listens.

    play_to_end(node) waits until the node's subscriptions to the played topics are matched,
    starts the playback, and spins the node until the player has played everything and its
    messages have been taken.
    """

    def __init__(self, recording: str, *, rate: float = 1.0, clock: Optional[float] = None,
                 topics: Optional[Sequence[str]] = None, start_offset: float = 0.0,
                 environ: Optional[Mapping[str, str]] = None):
        """clock: publish /clock at this rate (Hz) from the recorded time; None: no /clock."""
        self.recording = recording
        self.run: Run = open_run(recording)
        arguments = [recording, '--start-paused', '--rate', repr(rate),
                     '--start-offset', repr(start_offset)]
        if clock is not None:
            arguments += ['--clock', repr(clock)]
        self.topics = sorted(self.run.topics() if topics is None
                             else {absolute_topic(t) for t in topics})
        if topics is not None:
            arguments += ['--topics', *self.topics]
        self.process = _start_command('mcap_player', arguments, environ)

    def messages(self, topic: str) -> List[bytes]:
        """Return the serialized messages the replay plays on a topic, in order."""
        return [m.data for m in self.run.messages(topic)]

    def message_count(self, topic: str) -> int:
        """Return how many messages the replay plays on a topic."""
        return sum(1 for _ in self.run.messages(topic))

    def play(self, node: Node, timeout: float = 30.0) -> None:
        """Start the playback once the node's subscriptions to the played topics are matched."""
        listened = sorted({s.topic_name for s in node.subscriptions} & set(self.topics))
        spin_until(node, lambda: all(node.count_publishers(t) > 0 for t in listened), timeout,
                   'the player\'s publishers on ' + (', '.join(listened) or 'no topic'))
        client = node.create_client(Trigger, f'/{PLAYER_NODE_NAME}/resume')
        try:
            spin_until(node, client.service_is_ready, timeout, 'the player\'s resume service')
            future = client.call_async(Trigger.Request())
            spin_until(node, future.done, timeout, 'the player to start')
        finally:
            node.destroy_client(client)

    def play_to_end(self, node: Node, timeout: float = 60.0) -> int:
        """
        Play, spin the node until the player is done and its messages taken; exit code.

        The player waits for reliable subscribers to acknowledge every message before it
        ends, so they are all in the node's queues then: each spin takes one.
        """
        self.play(node, timeout)
        spin_until(node, lambda: not self.process.running, timeout, 'the end of the playback')
        listened = {s.topic_name for s in node.subscriptions} & set(self.topics)
        _spin_ready(node, sum(self.message_count(topic) for topic in listened) + IDLE_SPINS)
        return self.process.wait()

    def stop(self) -> int:
        """Stop the player (if still playing); return its exit code."""
        return self.process.stop()


def simulate(scenario: Union[str, Mapping[str, Any]], output: str, *, markers: bool = False,
             environ: Optional[Mapping[str, str]] = None, timeout: float = 600.0) -> str:
    """
    Simulate a scenario (a YAML file, or its content as a mapping) into output; return output.

    Runs qrm_simulate; RuntimeError with its message if it refuses or fails.
    """
    if not isinstance(scenario, str):
        path = output + '.yaml'
        with open(path, 'w', encoding='utf-8') as handle:
            yaml.safe_dump(dict(scenario), handle)
        scenario = path
    arguments = [_command('qrm_simulate'), scenario, '-o', output, '--progress', 'never']
    if markers:
        arguments.append('--markers')
    result = subprocess.run(arguments, capture_output=True, text=True, timeout=timeout,
                            env=dict(environ) if environ is not None else None)
    if result.returncode != 0:
        raise RuntimeError(f'qrm_simulate {scenario} failed ({result.returncode}): '
                           f'{result.stderr.strip()}')
    return output
