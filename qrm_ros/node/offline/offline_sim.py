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
shaper_sim run offline, as fast as the CPU allows: the node itself, ticked by a loop.

Nothing of the node is copied. The simulator is ShaperSimNode, started with use_sim_time and
with publishers that write each message, serialized by rclpy, into the run file (the
recorder's own McapRunFile) instead of sending it over DDS (the slower topics' bytes made the
exact message DDS would send: recording.typestore.exact_cdr). A loop calls, at each tick's
stamp, what the node's timer callback calls at its clock's time (publish_at), so the
steppers, the efforts, the stroke measurement, the diagnostics and the markers are the
node's; a scenario's events go in
between the ticks through the node's own paths: its parameter changes (judged by its rules,
with a /parameter_events message each), its speed-command subscription, its pause and reset
services. The channels carry the QoS and type hash the recorder would find for the node's
publishers, the metadata the records it would read from the node's parameters, and the
machine is written beside the joint states by the recorder's own MachineChannels. What differs
from a live recording: the log time of each message is the simulated time it was sent at,
not a wall-clock receive time; a stroke pair's report carries its effort theory, worked
out in the loop's own thread (the live node reports 'pending' while its worker process
works it out). The messages reach the file a batch at a time (WRITE_BATCH), in the order
they were sent.
"""

from collections import deque
import functools
import os
import time
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Sequence, Tuple

from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.common.names import (JOINT_STATE_TYPE, JOINT_STATES_TOPIC, LINKAGE_MARKERS_TOPIC,
                                       RAM_TWIST_TOPIC, SPEED_COMMAND_TOPIC)
from qrm_ros.core.common.units import NANOSECONDS_PER_SECOND
from qrm_ros.node.recorder.recorder import (DEFAULT_TOPICS, MAX_CHUNK_DURATION_RANGE,
                                            sim_metadata_records)
from qrm_ros.node.process.ros_process import init_rclpy
from qrm_ros.node.offline.scenario import Event, Scenario, ScenarioError
from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode
from qrm_ros.recording.machine_channels import MachineChannels
from qrm_ros.recording.mcap_run_file import COMPRESSIONS, McapRunFile
from qrm_ros.recording.typestore import exact_cdr
import rclpy
from rclpy.clock import ClockType, ROSClock
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.serialization import serialize_message
from rclpy.time import Time
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

__all__ = ['OfflineShaperSim', 'RecordingPublisher', 'Simulation', 'SimulationSummary',
           'THEORY_TIMEOUT', 'summary_line']

# s a live node's stroke-pair report may wait for its effort theory (worked out in a worker
# process) where it is to match an offline run's, which works it out in its own thread.
THEORY_TIMEOUT = 120.0
# s a run waits for the drives' compiled forms before its first tick.
KERNEL_LOAD_TIMEOUT = 30.0
# Longest log time per chunk: the longest the recorder allows, so chunks close by size
# (CHUNK_SIZE_BYTES). A live recording closes (and fsyncs) one a second, to lose at most that
# much to a crash; an offline run has nothing live to lose (it is made again), and its
# chunks of one second cost about 15 us a tick more than the messages' writing itself.
CHUNK_DURATION_NS = round(MAX_CHUNK_DURATION_RANGE[1] * NANOSECONDS_PER_SECOND)
# Messages handed to the run file together, with their joint states' machine transforms: the
# writing code then runs many times in a row, not once between two ticks of the node (which
# pushed it out of the processor's caches: about 15 us a tick more). The same calls in the
# same order, so the same file; only later (the node's messages are bytes by then).
WRITE_BATCH = 128


class RecordingPublisher(Publisher):
    """A publisher of the offline node: each message goes to `write`, which serializes it."""

    # Set once the run file has the topic's channel; until then messages are dropped (the
    # parameter declarations, as a recorder that starts after the node misses them).
    write: Optional[Callable[[Any], None]] = None

    def publish(self, msg) -> None:
        write = self.write
        if write is not None:
            write(msg)


class OfflineShaperSim(ShaperSimNode):
    """The shaper_sim node with RecordingPublishers; Simulation ticks it."""

    def __init__(self, markers: bool = False, **node_options):
        """markers: whether the linkage markers are recorded (else they are not even built)."""
        self.markers_recorded = markers
        super().__init__(**node_options)

    def create_publisher(self, msg_type, topic, qos_profile, **options):
        options['publisher_class'] = RecordingPublisher
        return super().create_publisher(msg_type, topic, qos_profile, **options)

    def set_marker_rate(self, rate):
        """Draw the markers at rate Hz if they are recorded (else not at all: nobody sees them)."""
        super().set_marker_rate(rate if self.markers_recorded else 0.0)


class SimulationSummary(NamedTuple):
    """What a run wrote: the file, the ticks, the messages per topic, the loop's wall time (s)."""

    path: str
    ticks: int
    topic_counts: Dict[str, int]
    loop_seconds: float
    stopped: bool  # stopped before the end (a stop request)


class Simulation:
    """
    One offline run of a scenario into an MCAP file; see the module docstring.

    Refused start-up values raise ValueError (the node's reason) before any file is made; a
    refused event raises ScenarioError and leaves no file; an existing output raises the
    recorder's ConfigurationError, a write error its RecorderError.
    """

    def __init__(self, scenario: Scenario, output: str,
                 topics: Sequence[str] = tuple(DEFAULT_TOPICS), markers: bool = False,
                 compression: str = 'zstd', context: Optional[Context] = None) -> None:
        self.scenario = scenario
        # (channel, log time, data, transforms) of the messages not handed to the run file yet
        # (WRITE_BATCH); transforms: None, or a joint state's (sec, nanosec, names, positions)
        # for its machine transforms (empty: from its bytes)
        self._writes: List[Tuple[int, int, bytes, Optional[tuple]]] = []
        self._own_context = context is None
        if context is None:
            context = Context()
            init_rclpy(args=[], context=context)
        self._context = context
        self._node: Optional[OfflineShaperSim] = None
        self._run_file: Optional[McapRunFile] = None
        self._now_ns = 0
        # Always on the simulated clock (last: a scenario's use_sim_time does not undo it).
        overrides = [Parameter(name, value=value) for name, value in
                     scenario.parameters.items()] + [Parameter('use_sim_time', value=True)]
        topics = list(topics) + ([LINKAGE_MARKERS_TOPIC] if markers else [])
        try:
            self._node = node = OfflineShaperSim(markers=markers, context=context,
                                                 parameter_overrides=overrides)
            node.stroke_pairs.theory_in_this_thread = True
            clock = node.get_clock()
            assert isinstance(clock, ROSClock)  # a node's clock is; use_sim_time drives it
            self._clock = clock
            self._speed_publisher = None
            if any(event.kind == 'input_speed_cmd' for event in scenario.events):
                # The commander's publisher, recorded as the recorder would record it.
                self._speed_publisher = node.create_publisher(Float64, SPEED_COMMAND_TOPIC, 10)
            speed_topic = node.resolve_topic_name(SPEED_COMMAND_TOPIC)
            self._speed_subscription = next(s for s in node.subscriptions
                                            if s.topic_name == speed_topic)
            self._run_file = McapRunFile(output, COMPRESSIONS[compression], CHUNK_DURATION_NS)
            # The machine beside the joint states, as the recorder writes it: the URDF and
            # fixed transforms at the first tick, each joint state's link transforms.
            self._machine = MachineChannels(self._run_file)
            self._add_channels(topics)
            stamps = self.tick_stamps()
            self._machine.start(node.geometry, stamps[0] if stamps else stamps.start)
            parameters = {name: node.get_parameter(name).value
                          for name in node.get_parameters_by_prefix('')}
            for name, data in sim_metadata_records(parameters)[0]:
                self._run_file.add_metadata(name, data)
        except BaseException:
            self.close(keep=False)
            raise

    @property
    def node(self) -> OfflineShaperSim:
        """The node being ticked."""
        assert self._node is not None
        return self._node

    @property
    def path(self) -> str:
        """The output file."""
        assert self._run_file is not None
        return self._run_file.path

    def _add_channels(self, topics: Sequence[str]) -> None:
        """Give each recorded topic that has a publisher its channel, as the recorder does."""
        node, run_file = self.node, self._run_file
        assert run_file is not None
        # Written at every tick: rclpy's bytes as they are (their length is exact).
        every_tick = {node.resolve_topic_name(RAM_TWIST_TOPIC)}
        for topic in topics:
            resolved = node.resolve_topic_name(topic)
            found = node.get_publishers_info_by_topic(resolved)
            if not found:
                continue  # the recorder subscribes only to topics with a publisher
            hashes = [str(info.topic_type_hash) for info in found]
            channel = run_file.add_channel(
                resolved, found[0].topic_type, [info.qos_profile for info in found],
                next((h for h in hashes if h.startswith('RIHS')), ''))
            joint_states = (found[0].topic_type == JOINT_STATE_TYPE
                            and resolved == node.resolve_topic_name(JOINT_STATES_TOPIC))
            if joint_states:
                write = self._write_joint_state
            elif resolved in every_tick:
                write = self._write
            else:
                write = functools.partial(self._write_exact, found[0].topic_type)
            for publisher in node.publishers:
                if isinstance(publisher, RecordingPublisher) and publisher.topic_name == resolved:
                    publisher.write = functools.partial(write, channel)

    def _write(self, channel: int, message: Any) -> None:
        now = self._now_ns
        data = message if isinstance(message, bytes) else serialize_message(message)
        self._queue(channel, now, data, None)

    def _write_exact(self, type_name: str, channel: int, message: Any) -> None:
        """Write a message of the slower topics as DDS would send it (exact_cdr)."""
        now = self._now_ns
        data = exact_cdr(message, type_name)
        self._queue(channel, now, data, None)

    def _write_joint_state(self, channel: int, message: Any) -> None:
        now = self._now_ns
        if isinstance(message, bytes):
            self._queue(channel, now, message, ())
            return
        # The machine's transforms from the message's own values: no decoding of its bytes.
        # The positions are the message's own array, which the next tick replaces (rclpy's
        # setter copies what it is given), not changes.
        stamp = message.header.stamp
        self._queue(channel, now, serialize_message(message),
                    (stamp.sec, stamp.nanosec, message.name, message.position))

    def _queue(self, channel: int, now: int, data: bytes, transforms: Optional[tuple]) -> None:
        writes = self._writes
        writes.append((channel, now, data, transforms))
        if len(writes) >= WRITE_BATCH:
            self._write_queued()

    def _write_queued(self) -> None:
        """Hand what was sent so far to the run file, each joint state's transforms after it."""
        writes, self._writes = self._writes, []
        if self._run_file is None:
            return
        add_message, machine = self._run_file.add_message, self._machine
        for channel, now, data, transforms in writes:
            add_message(channel, now, now, data)
            if transforms:
                machine.joint_state_values(now, now, data, *transforms)
            elif transforms is not None:
                machine.joint_state(now, now, data)

    def _set_clock(self, stamp_ns: int) -> None:
        self._now_ns = stamp_ns
        self._clock.set_ros_time_override(Time(nanoseconds=stamp_ns,
                                               clock_type=ClockType.ROS_TIME))

    def _apply(self, event: Event) -> None:
        """Do an event through the node's own path (between two ticks)."""
        node = self.node
        if event.kind == 'set':
            result = node.set_parameters_atomically(
                [Parameter(name, value=value) for name, value in event.value.items()])
            if not result.successful:
                raise ScenarioError(f'event at {event.at:g} s refused by the node: '
                                    f'{result.reason}')
        elif event.kind == 'input_speed_cmd':
            message = Float64(data=event.value)
            if self._speed_publisher is not None:
                self._speed_publisher.publish(message)
            self._speed_subscription.callback(message)
        elif event.kind in ('pause', 'resume'):
            node.on_pause(SetBool.Request(data=event.kind == 'pause'), SetBool.Response())
        else:
            node.on_reset(Trigger.Request(), Trigger.Response())

    def tick_stamps(self) -> range:
        """Return the stamps (ns) of the ticks: from a period after the start to its end."""
        rate = self.node.get_parameter('publish_rate').value
        period_ns = round(NANOSECONDS_PER_SECOND / rate)
        start_ns = round(self.scenario.start_time * NANOSECONDS_PER_SECOND)
        end_ns = start_ns + round(self.scenario.duration * NANOSECONDS_PER_SECOND)
        return range(start_ns + period_ns, end_ns + 1, period_ns)

    def run(self, progress: Optional[Callable[[float], None]] = None,
            stop: object = False) -> SimulationSummary:
        """
        Run the scenario and finish the file; return what was written.

        progress(seconds): called with the simulated seconds done, about once per simulated
        second. stop: a stop request (truthy once asked, e.g. ros_process.StopRequest): the
        file is finished with what was simulated so far.
        """
        node, run_file = self.node, self._run_file
        assert run_file is not None
        stamps = self.tick_stamps()
        start_ns = round(self.scenario.start_time * NANOSECONDS_PER_SECOND)
        events = deque((start_ns + round(e.at * NANOSECONDS_PER_SECOND), e)
                       for e in self.scenario.events)
        self._set_clock(start_ns)
        # The drives' compiled forms load on a thread (0.3-1 s): the same numbers, faster;
        # worth it for every tick of a run (the live node's speed drive does without).
        COMPILED_DRIVE_KERNEL.start_loading()  # once per process
        COMPILED_DRIVE_KERNEL.loaded.wait(KERNEL_LOAD_TIMEOUT)
        progress_every = max(1, round(NANOSECONDS_PER_SECOND / stamps.step))
        publish_at, wait_for_reports, set_clock = (node.publish_at, node.wait_for_pair_reports,
                                                   self._set_clock)
        ticks, stopped, clock_ns = 0, False, start_ns
        started = time.perf_counter()
        try:
            for stamp_ns in stamps:
                if events and events[0][0] <= stamp_ns:
                    set_clock(clock_ns)  # the events come at the last tick's time
                    while events and events[0][0] <= stamp_ns:
                        self._apply(events.popleft()[1])
                clock_ns = self._now_ns = stamp_ns
                if node.paused:
                    set_clock(stamp_ns)
                    node.on_timer()
                else:
                    # What the timer's callback does at the clock's time, with the time
                    # given: the node's clock is set only where something reads it (the
                    # events, a paused tick), which the ticks do not.
                    publish_at(stamp_ns)
                wait_for_reports()
                ticks += 1
                if stop:
                    stopped = True
                    break
                if progress is not None and ticks % progress_every == 0:
                    progress((stamp_ns - start_ns) / NANOSECONDS_PER_SECOND)
            self._write_queued()  # the last batch
            loop_seconds = time.perf_counter() - started
            set_clock(clock_ns)
            node.wait_for_pair_reports()
        except BaseException:
            self.close(keep=False)
            raise
        counts = self.close(keep=True)
        return SimulationSummary(run_file.path, ticks, counts, loop_seconds, stopped)

    def close(self, keep: bool = True) -> Dict[str, int]:
        """Finish the file (keep) or remove it; let go of the node and the context."""
        counts: Dict[str, int] = {}
        node, self._node = self._node, None
        if node is not None:
            node.destroy_node()  # the last pairs are reported into the file first
        run_file = self._run_file
        if run_file is not None:
            try:
                if keep:
                    self._write_queued()  # the last pairs' reports (destroy_node), the rest
                counts = run_file.topic_counts()
                if not run_file.failed:  # a failed write has let go of the file already
                    run_file.finish()
            finally:
                self._run_file = None
                if not keep:
                    _remove(run_file.path)
        if self._own_context:
            self._own_context = False
            rclpy.try_shutdown(context=self._context)
        return counts


def _remove(path: str) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def summary_line(summary: SimulationSummary) -> str:
    """One line on what a run wrote."""
    counts = ', '.join(f'{topic} {count}' for topic, count in sorted(
        summary.topic_counts.items()))
    return f'wrote {summary.path}: {summary.ticks} ticks; {counts}'
