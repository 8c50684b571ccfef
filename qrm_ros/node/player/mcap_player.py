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
The ``mcap_player`` node: a recorded run played back onto its topics, as ``ros2 bag play`` does.

Each message goes out as the serialized bytes it was recorded as (no decoding), on a
publisher with the QoS its recorded publishers offered (rosbag2's ``offered_qos_profiles``
channel metadata), at the recorded timing: the log-time gap to the message before, divided
by the rate. The wait before a message is slept to within BUSY_WAIT_NS of it and spun the
rest of the way, so a message leaves within microseconds of its time. Services pause, resume
and toggle the playback, and publish the next message while paused (``~/play_next``), as
rosbag2's player does; ``/clock`` from the recorded time lets ``use_sim_time`` nodes follow.

Files are read by qrm_ros.recording.bag_reader: recordings of mcap_recorder, qrm_simulate and
rosbag2 (``ros2 bag record -s mcap``); a damaged part is skipped and reported, the rest plays.
"""

from array import array
import importlib
import sys
import threading
import time
from typing import Any, Dict, Iterator, List, NamedTuple, Optional, Sequence

from builtin_interfaces.msg import Time as TimeMessage
from qrm_ros.core.common.names import absolute_topic
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.node.process.ros_process import RCLError
from qrm_ros.recording.bag_reader import Loss, MessageTuple, Run
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger
import yaml

__all__ = ['ACK_TIMEOUT', 'BUSY_WAIT_NS', 'CLOCK_QOS', 'DEFAULT_CLOCK_RATE',
           'GIL_SWITCH_INTERVAL', 'McapPlayer', 'OPTION_RANGES', 'PLAYER_DEPTH',
           'PLAYER_NODE_NAME', 'PlayOptions', 'PlaybackError', 'TIMING_SAMPLES', 'message_class',
           'played_qos']

PLAYER_NODE_NAME = 'mcap_player'
# The last stretch of a wait (ns) is spun, not slept: a sleep overshoots by up to a
# millisecond or more on a loaded machine, a spin by microseconds.
BUSY_WAIT_NS = 2_000_000
# s: the longest the service thread may hold the GIL while a message is due (Python's
# default, 5 ms, would let it delay a message by that much).
GIL_SWITCH_INTERVAL = 1e-4
# Messages whose send lateness is kept for timing_summary (8 bytes each; the first ones).
TIMING_SAMPLES = 100_000
# Longest single sleep (s): a stop request or a pause is seen within it.
SLEEP_SLICE = 0.05
# History depth of a topic whose recorded depth is unknown (discovery does not tell it).
PLAYER_DEPTH = 1000
# s the player waits at the end for reliable subscribers to acknowledge what it sent, per
# topic (it would otherwise exit with the last messages still to be resent).
ACK_TIMEOUT = 2.0
# Hz: /clock's rate when --clock is given without one (ros2 bag play's default).
DEFAULT_CLOCK_RATE = 40.0
# /clock as rclpy's and rclcpp's time sources subscribe to it.
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


class PlaybackError(Exception):
    """Options the player cannot follow (a one-line reason; exit code 2)."""


# The ranges of PlayOptions' numbers (the command refuses others): times in s up to the
# largest ROS time (builtin_interfaces/Time.sec is an int32); the rate within a million
# either way (beyond, a gap of the run in ns overflows, or nothing is timed any more);
# /clock from one message in 100 s to 10 kHz.
OPTION_RANGES = {'rate': (1e-6, 1e6), 'start_offset': (0.0, 2.0 ** 31 - 1),
                 'delay': (0.0, 2.0 ** 31 - 1), 'clock_rate': (0.01, 1e4)}


class PlayOptions(NamedTuple):
    """What ``ros2 bag play`` users know: rate, loop, topics, start offset, delay, clock."""

    rate: float = 1.0
    loop: bool = False
    topics: Optional[Sequence[str]] = None  # None: every topic
    start_offset: float = 0.0  # s into the recording
    delay: float = 0.0  # s before the first message
    clock_rate: Optional[float] = None  # Hz of /clock; None: no /clock
    start_paused: bool = False


def message_class(type_name: str) -> Any:
    """Return the message class of 'pkg/msg/Type' (ImportError/ValueError if unknown)."""
    package, kind, name = type_name.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.{kind}'), name)
    except AttributeError:
        raise ImportError(f'no message {name} in {package}.{kind}') from None


def played_qos(offered_qos_profiles: str) -> QoSProfile:
    """
    Return the QoS to play a topic with, from its recorded ``offered_qos_profiles`` YAML.

    Reliable if every recorded publisher was, transient-local if every one was (rosbag2's
    rule); keep-last with the deepest recorded depth, PLAYER_DEPTH where none is known.
    """
    try:
        profiles = yaml.safe_load(offered_qos_profiles or '[]') or []
    except yaml.YAMLError:
        profiles = []
    if not isinstance(profiles, list):
        profiles = []
    profiles = [p for p in profiles if isinstance(p, dict)]

    def all_are(key: str, value: str) -> bool:
        return bool(profiles) and all(str(p.get(key, '')).lower() == value for p in profiles)
    depths = [p.get('depth') for p in profiles if isinstance(p.get('depth'), int)]
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=max(depths + [0]) or PLAYER_DEPTH,
        reliability=(ReliabilityPolicy.RELIABLE if all_are('reliability', 'reliable')
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL
                    if all_are('durability', 'transient_local')
                    else DurabilityPolicy.VOLATILE))


class McapPlayer(Node):
    """Plays one run file; play() runs in the caller's thread, the services on an executor."""

    def __init__(self, run: Run, options: PlayOptions = PlayOptions(), **node_options):
        super().__init__(PLAYER_NODE_NAME, **node_options)
        if not (options.rate > 0.0 and options.rate < float('inf')):
            raise PlaybackError(f'rate {options.rate!r} must be a finite factor > 0')
        self.run = run
        self.options = options
        self.losses: List[Loss] = []
        self.skipped: Dict[str, str] = {}  # topic -> why it is not played
        # topic -> [messages DDS refused to publish (bytes that do not fit the type), why]
        self.refused: Dict[str, List[Any]] = {}
        self.published = 0
        # ns each message was handed to its publisher after its due time (the first
        # TIMING_SAMPLES): the player's own timing, apart from the transport's and the
        # receiver's.
        self.lateness_ns = array('q')
        self._topic_publishers: Dict[str, Any] = {}
        self._playback_state = threading.Condition()
        self._paused = options.start_paused
        self._steps = 0
        topics = run.topics()
        wanted = (set(topics) if options.topics is None
                  else {absolute_topic(t) for t in options.topics})
        unknown = sorted(wanted - set(topics))
        if unknown:
            raise PlaybackError(f'topics {", ".join(unknown)} are not in {run.path!r}; it has '
                                f'{", ".join(sorted(topics)) or "none"}')
        for topic in sorted(wanted):
            self._add_publisher(topic, topics[topic])
        self._clock_publisher = (self.create_publisher(Clock, '/clock', CLOCK_QOS)
                                 if options.clock_rate else None)
        for name, callback in (('pause', self._on_pause), ('resume', self._on_resume),
                               ('toggle_paused', self._on_toggle),
                               ('play_next', self._on_play_next)):
            self.create_service(Trigger, f'~/{name}', callback)

    def _add_publisher(self, topic: str, type_name: str) -> None:
        try:
            kind = message_class(type_name)
        except (ImportError, ValueError) as error:
            self.skipped[topic] = f'type {type_name!r} cannot be imported ({error})'
            return
        qos = played_qos(self.run.channel_metadata(topic).get('offered_qos_profiles', ''))
        self._topic_publishers[topic] = self.create_publisher(kind, topic, qos)

    @property
    def topics(self) -> List[str]:
        """The topics played."""
        return sorted(self._topic_publishers)

    # Services -------------------------------------------------------------------------------

    def _answer(self, response, success: bool, message: str):
        response.success, response.message = success, message
        return response

    def _set_paused(self, paused: bool) -> None:
        with self._playback_state:
            self._paused = paused
            self._playback_state.notify_all()

    @property
    def paused(self) -> bool:
        """Whether the playback is paused."""
        return self._paused

    def _on_pause(self, request, response):
        self._set_paused(True)
        return self._answer(response, True, 'paused')

    def _on_resume(self, request, response):
        self._set_paused(False)
        return self._answer(response, True, 'playing')

    def _on_toggle(self, request, response):
        self._set_paused(not self._paused)
        return self._answer(response, True, 'paused' if self._paused else 'playing')

    def _on_play_next(self, request, response):
        with self._playback_state:
            if not self._paused:
                return self._answer(response, False, 'not paused: pause first')
            self._steps += 1
            self._playback_state.notify_all()
        return self._answer(response, True, 'publishing the next message')

    # Playing --------------------------------------------------------------------------------

    def _messages(self) -> Iterator[MessageTuple]:
        """Yield the messages to play, from the start offset on, noting the losses."""
        first: Optional[int] = self.run.start_time
        offset_ns = round(self.options.start_offset * NANOSECONDS_PER_SECOND)
        for message in self.run.messages(self.topics, on_loss=self.losses.append):
            if first is None:
                first = message.log_time
            if message.log_time - first >= offset_ns:
                yield message

    def _wait_until(self, target_ns: int, stop: object, origin: List[int],
                    first_log_ns: int, log_ns: int) -> bool:
        """
        Wait until perf_counter_ns reaches target_ns, sending /clock meanwhile (up to log_ns).

        Returns False on a stop request. A pause moves origin[0] (and the target) by its length.
        """
        rate, clock = self.options.rate, self._clock_publisher
        clock_rate = self.options.clock_rate
        clock_period = round(NANOSECONDS_PER_SECOND / clock_rate) if clock_rate else 0
        while True:
            if stop:
                return False
            if self._paused:
                paused_at = time.perf_counter_ns()
                with self._playback_state:
                    while self._paused and not self._steps and not stop:
                        self._playback_state.wait(SLEEP_SLICE)
                    if self._steps:
                        self._steps -= 1
                        # The next message now; the ones after it keep their gaps to it.
                        origin[0] += time.perf_counter_ns() - target_ns
                        return True
                origin[0] += time.perf_counter_ns() - paused_at
                target_ns += time.perf_counter_ns() - paused_at
                continue
            now = time.perf_counter_ns()
            if clock is not None and now >= origin[1]:
                # Held at the first message's time while the delay runs.
                recorded = min(log_ns, first_log_ns + max(0, round((now - origin[0]) * rate)))
                clock.publish(Clock(clock=_time_message(recorded)))
                origin[1] = now + clock_period
            until = min(target_ns, origin[1]) if clock is not None else target_ns
            remaining = until - now
            if remaining <= 0:
                if until == target_ns:
                    return True
                continue
            if remaining > BUSY_WAIT_NS:
                time.sleep(min(SLEEP_SLICE, (remaining - BUSY_WAIT_NS) / NANOSECONDS_PER_SECOND))
                continue
            while time.perf_counter_ns() < until:
                pass

    def play(self, stop: object = False) -> bool:
        """
        Play the run (again and again with loop); return False if stopped before its end.

        stop: a stop request, truthy once asked (ros_process.StopRequest).
        """
        if sys.getswitchinterval() > GIL_SWITCH_INTERVAL:
            sys.setswitchinterval(GIL_SWITCH_INTERVAL)
        rate = self.options.rate
        delay_ns = round(self.options.delay * NANOSECONDS_PER_SECOND)
        # [wall origin of the recorded first message, next /clock time]: moved by pauses.
        origin = [time.perf_counter_ns() + delay_ns, 0]
        while True:
            first_log_ns: Optional[int] = None
            for message in self._messages():
                if first_log_ns is None:
                    first_log_ns = message.log_time
                    origin[0] = max(origin[0], time.perf_counter_ns())
                target = origin[0] + round((message.log_time - first_log_ns) / rate)
                if not self._wait_until(target, stop, origin, first_log_ns, message.log_time):
                    return False
                if len(self.lateness_ns) < TIMING_SAMPLES:  # against the target a pause moved
                    self.lateness_ns.append(time.perf_counter_ns() - origin[0] - round(
                        (message.log_time - first_log_ns) / rate))
                try:
                    self._topic_publishers[message.topic].publish(message.data)
                except RCLError as error:  # e.g. a message longer than its fixed-size type
                    self._note_refusal(message, error)
                    continue
                self.published += 1
            if not self.options.loop or first_log_ns is None or stop:
                if not stop:
                    self.wait_for_acknowledgements()
                return not stop
            origin[0] = time.perf_counter_ns()
            self.losses = []  # counted once, not per loop

    def _note_refusal(self, message: MessageTuple, error: Exception) -> None:
        """Count a message DDS refused; say so once per topic (the rest plays on)."""
        refused = self.refused.setdefault(message.topic, [0, str(error).strip()])
        refused[0] += 1
        if refused[0] == 1:
            self.get_logger().warning(
                f'a message on {message.topic} (log time {message.log_time} ns) was refused '
                f'by DDS ({refused[1]}): its bytes do not fit the type; it and any others like '
                'it are skipped')

    def timing_summary(self) -> Optional[str]:
        """Say how late the messages were sent (median, 99th percentile, ms); None if none."""
        lateness = sorted(self.lateness_ns)
        if not lateness:
            return None
        median = lateness[len(lateness) // 2] / 1e6
        p99 = lateness[min(len(lateness) - 1, round(0.99 * (len(lateness) - 1)))] / 1e6
        return (f'sent after their recorded time by {median:.3f} ms (median), {p99:.3f} ms '
                f'(99th percentile) over {len(lateness)} messages')

    def wait_for_acknowledgements(self) -> None:
        """Wait (at most ACK_TIMEOUT) until reliable subscribers have every message."""
        for publisher in self._topic_publishers.values():
            publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT))


def _time_message(stamp_ns: int) -> TimeMessage:
    seconds, nanoseconds = divmod(stamp_ns, NANOSECONDS_PER_SECOND)
    return TimeMessage(sec=seconds, nanosec=nanoseconds)
