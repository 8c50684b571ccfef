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
The executors the processes spin on (qrm_ros.node.process.ros_process), over real DDS.

rclpy's EventsExecutor is experimental in Jazzy; what this package relies on is checked here
against the SingleThreadedExecutor (the fallback, QRM_ROS_EXECUTOR=single): timers on
simulated time (/clock steps, a pause of /clock, jumps forward and back), timer cancel and
reset, the node's services and parameter services, and its refusal of guard conditions.
"""

import contextlib
import math
import statistics
import time

from builtin_interfaces.msg import Time
import pytest
from qrm_ros.node.process.ros_process import (EXECUTOR_VARIABLE, ExecutorChoiceError,
                                              executor_kind, init_rclpy, MESSAGE_INFO_SIGNATURE,
                                              message_and_info, new_executor)
from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode
from rcl_interfaces.srv import DescribeParameters, SetParametersAtomically
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from ros_probe import stamp_ns, wait_for
from shaper_process import NS, Process, Probe, wrapped

KINDS = ['events', 'single']
SIM_START_NS = 1000 * NS  # the first /clock value the tests send
SIM_STEP_NS = 10_000_000  # one publish period of the node at its default 100 Hz


def clock_message(nanoseconds):
    return Clock(clock=Time(sec=nanoseconds // NS, nanosec=nanoseconds % NS))


# Choosing the executor ----------------------------------------------------------------------

def test_the_executor_is_chosen_by_the_environment():
    assert executor_kind({}) == 'events'
    assert executor_kind({EXECUTOR_VARIABLE: ''}) == 'events'
    assert executor_kind({EXECUTOR_VARIABLE: ' Single '}) == 'single'
    assert executor_kind({EXECUTOR_VARIABLE: 'events'}) == 'events'
    with pytest.raises(ExecutorChoiceError) as refused:
        executor_kind({EXECUTOR_VARIABLE: 'multi'})
    assert str(refused.value) == (f"{EXECUTOR_VARIABLE}='multi' is not an executor: allowed "
                                  'events, single (unset: events)')
    context = Context()
    init_rclpy(context=context)
    try:
        single = new_executor('single', context=context)
        assert isinstance(single, SingleThreadedExecutor)
        events = new_executor('events', context=context)
        assert type(events).__name__ == 'EventsExecutor'
        for executor in (single, events):
            executor.shutdown()
    finally:
        rclpy.shutdown(context=context)


def test_a_bad_executor_choice_stops_the_node_at_start_up_with_exit_2():
    code, output = Process(environment={EXECUTOR_VARIABLE: 'multi'}).stop(None, timeout=30.0)
    assert code == 2, output
    assert 'Traceback' not in output, output
    assert f"shaper_sim: cannot start: {EXECUTOR_VARIABLE}='multi' is not an executor" in output


# In this process: timers on simulated time, cancel, reset, guard conditions ---------------

class SimTimeBench:
    """A use_sim_time node with a 10 ms timer on `kind`, and a /clock publisher."""

    def __init__(self, kind):
        self.context, self.clock_context = Context(), Context()
        init_rclpy(context=self.context)
        rclpy.init(context=self.clock_context)
        self.node = Node('sim_time_timer', context=self.context,
                         parameter_overrides=[Parameter('use_sim_time', value=True)])
        self.ticks = []
        self.timer = self.node.create_timer(
            SIM_STEP_NS / NS, lambda: self.ticks.append(self.node.get_clock().now().nanoseconds))
        self.executor = new_executor(kind, context=self.context)
        self.executor.add_node(self.node)
        self.clock_node = Node('clock_source', context=self.clock_context)
        self.clock_publisher = self.clock_node.create_publisher(Clock, '/clock', 10)
        wait_for(lambda: self.clock_publisher.get_subscription_count() > 0, 10.0,
                 'the node subscribing to /clock')
        self.sim_ns = SIM_START_NS

    def spin(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)

    def spin_until(self, predicate, what, timeout=10.0, fail=True):
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > end:
                assert not fail, f'timed out waiting for {what}'
                return
            self.executor.spin_once(timeout_sec=0.005)

    def step(self, steps, step_ns=SIM_STEP_NS):
        """Advance simulated time by `steps` steps, each once the node has taken the last."""
        for _ in range(steps):
            self.sim_ns += step_ns
            deadline = time.monotonic() + 10.0
            while self.node.get_clock().now().nanoseconds != self.sim_ns:
                assert time.monotonic() < deadline, f'the node clock never took {self.sim_ns}'
                # Again until taken: rclpy's /clock subscription is best effort.
                self.clock_publisher.publish(clock_message(self.sim_ns))
                self.spin_until(
                    lambda: self.node.get_clock().now().nanoseconds == self.sim_ns,
                    'the step', timeout=0.2, fail=False)
            self.spin(0.002)  # a timer made due by the step runs now

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.clock_node.destroy_node()
        rclpy.shutdown(context=self.context)
        rclpy.shutdown(context=self.clock_context)


@pytest.fixture(params=KINDS)
def sim_time_bench(request):
    made = SimTimeBench(request.param)
    yield made
    made.close()


def test_timers_follow_simulated_time(sim_time_bench):
    bench = sim_time_bench
    bench.spin(0.2)
    assert bench.ticks == [], 'a timer ran before any /clock'
    bench.step(50)
    # One tick per 10 ms step, at the /clock value (rcl's timer runs on the ROS clock).
    expected = [SIM_START_NS + k * SIM_STEP_NS for k in range(1, 51)]
    assert bench.ticks[-45:] == expected[-45:], bench.ticks

    # /clock pauses: the timer stops although wall time goes on.
    count = len(bench.ticks)
    bench.spin(0.3)
    assert len(bench.ticks) == count

    # A jump forward of 10 s: one tick (rcl skips the missed periods), then steady again.
    bench.step(1, 10 * NS)
    bench.step(5)
    assert bench.ticks[count:] == [bench.sim_ns - k * SIM_STEP_NS for k in range(5, -1, -1)]

    # A jump back (simulated time restarted): the timer keeps ticking on the new time.
    count = len(bench.ticks)
    bench.sim_ns = SIM_START_NS // 2
    bench.step(20)
    assert len(bench.ticks) - count >= 19
    assert all(SIM_START_NS // 2 < tick <= bench.sim_ns for tick in bench.ticks[count:])
    assert bench.ticks[-1] == bench.sim_ns


def test_a_cancelled_timer_stops_and_a_reset_one_runs_again(sim_time_bench):
    bench = sim_time_bench
    bench.step(5)
    bench.timer.cancel()
    count = len(bench.ticks)
    bench.step(10)
    assert len(bench.ticks) == count and bench.timer.is_canceled()
    bench.timer.reset()
    bench.step(10)
    assert bench.ticks[count:] == [bench.sim_ns - k * SIM_STEP_NS for k in range(9, -1, -1)]


@contextlib.contextmanager
def _node_with_executor(kind, name):
    """Yield a plain node and an executor of that kind, in a context of their own."""
    context = Context()
    init_rclpy(context=context)
    node = Node(name, context=context)
    executor = new_executor(kind, context=context)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def _spin_while(executor, condition, timeout=10.0):
    """Spin while condition() holds, at most timeout seconds."""
    deadline = time.monotonic() + timeout
    while condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


@pytest.mark.parametrize('kind', KINDS)
def test_a_wall_timer_is_cancelled_and_reset(kind):
    with _node_with_executor(kind, 'wall_timer') as (node, executor):
        ticks = []
        timer = node.create_timer(0.005, lambda: ticks.append(time.monotonic()))
        executor.add_node(node)
        _spin_while(executor, lambda: len(ticks) < 5)
        assert len(ticks) >= 5
        timer.cancel()
        count = len(ticks)
        end = time.monotonic() + 0.2
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)
        assert len(ticks) == count
        timer.reset()
        _spin_while(executor, lambda: len(ticks) < count + 5)
        assert len(ticks) >= count + 5


@pytest.mark.parametrize('kind', KINDS)
def test_marker_rate_changed_while_spinning(kind):
    """marker_rate stops the markers and restarts them at a new rate while the node spins."""
    context = Context()
    init_rclpy(context=context)
    node = ShaperSimNode(context=context, parameter_overrides=[
        Parameter('marker_rate', value=50.0)])
    listener = Node('marker_listener', context=context)
    executor = new_executor(kind, context=context)
    arrays = []
    listener.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)

    def spin(seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)

    def spin_until(count, what):
        end = time.monotonic() + 10.0
        while len(arrays) < count:
            assert time.monotonic() < end, f'timed out waiting for {what}'
            executor.spin_once(timeout_sec=0.01)
    try:
        executor.add_node(node)
        executor.add_node(listener)
        spin_until(5, 'markers at 50 Hz')
        assert node.set_parameters([Parameter('marker_rate', value=0.0)])[0].successful
        spin(0.1)  # markers already under way arrive
        count = len(arrays)
        spin(0.3)  # 15 periods at the old rate: none may come
        assert len(arrays) == count
        assert node.set_parameters([Parameter('marker_rate', value=200.0)])[0].successful
        spin_until(count + 40, 'markers at 200 Hz')
        # At most publish_rate (100 Hz): one array per tick, 10 ms apart in the stamps that
        # the node's clock gave them (the old rate would give 20 ms; a missed tick on a busy
        # machine makes one gap longer, not the median).
        stamps = [stamp_ns(array.markers[0]) for array in arrays[count:]]
        gaps = [later - earlier for earlier, later in zip(stamps, stamps[1:])]
        assert statistics.median(gaps) == pytest.approx(1e9 / 100.0, rel=0.1), gaps
    finally:
        executor.shutdown()
        node.destroy_node()
        listener.destroy_node()
        rclpy.shutdown(context=context)


@pytest.mark.parametrize('raw', [True, False], ids=['raw', 'message'])
@pytest.mark.parametrize('kind', KINDS)
def test_a_message_info_callback_gets_the_info_on_either_executor(kind, raw):
    # rclpy 7.1's EventsExecutor passes (message, info) as one argument; see ros_process.
    with _node_with_executor(kind, 'message_info') as (node, executor):
        received = []

        def on_message(*arguments):
            received.append(message_and_info(arguments))
        on_message.__signature__ = MESSAGE_INFO_SIGNATURE
        node.create_subscription(Float64, 'message_info_check', on_message, 10, raw=raw)
        publisher = node.create_publisher(Float64, 'message_info_check', 10)
        executor.add_node(node)
        wait_for(lambda: publisher.get_subscription_count() > 0, 10.0, 'the subscription')
        before = time.time_ns()
        for value in (1.0, 2.0, 3.0):
            publisher.publish(Float64(data=value))
        _spin_while(executor, lambda: len(received) < 3)
        assert len(received) == 3
        for (message, info), value in zip(received, (1.0, 2.0, 3.0)):
            if raw:
                assert isinstance(message, bytes) and len(message) == 12  # CDR header + double
            else:
                assert message.data == value
            assert before <= info['source_timestamp'] <= info['received_timestamp'] <= (
                time.time_ns())


def test_the_events_executor_refuses_guard_conditions_and_the_node_has_none():
    context = Context()
    init_rclpy(context=context)
    try:
        node = ShaperSimNode(context=context)
        # The node's entities: no guard condition anywhere, so the EventsExecutor takes it.
        assert not list(node.guards)
        assert all(w.get_num_entities().num_guard_conditions == 0 for w in node.waitables)
        executor = new_executor('events', context=context)
        executor.add_node(node)
        executor.spin_once(timeout_sec=0.05)
        executor.shutdown()
        node.destroy_node()

        other = Node('with_guard_condition', context=context)
        other.create_guard_condition(lambda: None)
        executor = new_executor('events', context=context)
        executor.add_node(other)
        with pytest.raises(RuntimeError, match='Guard conditions not supported'):
            for _ in range(10):
                executor.spin_once(timeout_sec=0.01)
        executor.shutdown()
        other.destroy_node()
    finally:
        rclpy.shutdown(context=context)


# The shaper_sim process over DDS ----------------------------------------------------------

@pytest.fixture
def probe():
    made = Probe()
    yield made
    made.close()


@pytest.mark.parametrize('kind', KINDS)
def test_the_node_publishes_on_simulated_time(probe, kind):
    """Joint-state stamps are the /clock values; no /clock, no joint states."""
    clock_publisher = probe.node.create_publisher(Clock, '/clock', 10)
    node = Process('-p', 'use_sim_time:=true', environment={EXECUTOR_VARIABLE: kind})
    sent = []

    def advance(steps, start=None):
        for _ in range(steps):
            sent.append(start if start is not None else sent[-1] + SIM_STEP_NS)
            start = None
            clock_publisher.publish(clock_message(sent[-1]))
            time.sleep(SIM_STEP_NS / NS)
    try:
        probe.wait_for(lambda: clock_publisher.get_subscription_count() > 0,
                       what='shaper_sim subscribing to /clock')
        probe.wait_for_discovery()
        time.sleep(0.3)
        assert not probe.messages, 'joint states before any /clock'
        advance(150, SIM_START_NS)
        probe.wait_for(lambda: probe.messages and stamp_ns(probe.messages[-1]) == sent[-1],
                       what='the last /clock value as a stamp')
        # /clock stops: publishing stops.
        time.sleep(0.1)
        count = len(probe.messages)
        time.sleep(0.4)
        assert len(probe.messages) == count, 'joint states while /clock was paused'
        resumed = len(sent)
        advance(50, sent[-1] + SIM_STEP_NS)
        probe.wait_for(lambda: stamp_ns(probe.messages[-1]) == sent[-1],
                       what='publishing after /clock resumed')
        # Simulated time restarts earlier: the node holds its state and continues from it.
        restarted = len(sent)
        advance(50, SIM_START_NS // 2)
        probe.wait_for(lambda: stamp_ns(probe.messages[-1]) == sent[-1],
                       what='publishing after /clock went back')
        messages = list(probe.messages)
    finally:
        code, output = node.stop()
    assert code == 0 and 'Traceback' not in output, output
    assert 'node clock went back' in output, output

    stamps = [stamp_ns(m) for m in messages]
    assert set(stamps) <= set(sent), 'a stamp that is no /clock value'
    # Nearly every 10 ms step of /clock gives one sample (the first waits for the timer).
    for first, last in ((0, resumed), (resumed, restarted), (restarted, len(sent))):
        window = set(sent[first:last])
        got = [s for s in stamps if s in window]
        assert len(got) >= 0.9 * (last - first), (first, last, len(got))
        assert got == sorted(got)
    # The state moves by simulated, not wall, time: the input angle advances by speed x the
    # stamp difference (constant speed, no command).
    speed = messages[0].velocity[0]
    for before, after in zip(messages, messages[1:]):
        dt = (stamp_ns(after) - stamp_ns(before)) / NS
        if dt > 0:
            assert abs(wrapped(after.position[0] - before.position[0] - speed * dt)) < 1e-9


def test_services_and_parameter_services_on_the_events_executor(probe):
    node = Process(environment={EXECUTOR_VARIABLE: 'events'})
    try:
        probe.wait_for(lambda: len(probe.messages) >= 3, what='first joint states')
        describe = probe.node.create_client(DescribeParameters,
                                            '/shaper_sim/describe_parameters')
        described, = probe.call(describe, DescribeParameters.Request(
            names=['coupling_offset'])).descriptors
        assert described.name == 'coupling_offset'
        assert '[-0.0225, 0.0225]' in described.additional_constraints
        assert described.floating_point_range[0].to_value == pytest.approx(0.0225)

        atomic = probe.node.create_client(SetParametersAtomically,
                                          '/shaper_sim/set_parameters_atomically')
        result = probe.call(atomic, SetParametersAtomically.Request(parameters=[
            Parameter('input_speed', value=5.0).to_parameter_msg(),
            Parameter('coupling_offset', value=0.03).to_parameter_msg()])).result
        assert not result.successful and '[-0.0225, 0.0225] m' in result.reason
        result = probe.call(atomic, SetParametersAtomically.Request(parameters=[
            Parameter('input_speed', value=5.0).to_parameter_msg(),
            Parameter('coupling_offset', value=0.002).to_parameter_msg()])).result
        assert result.successful, result.reason
        assert probe.get_parameters(['input_speed', 'coupling_offset']) == {
            'input_speed': 5.0, 'coupling_offset': 0.002}

        pause = probe.node.create_client(SetBool, '/shaper_sim/pause')
        assert probe.call(pause, SetBool.Request(data=True)).message == 'paused'
        time.sleep(0.1)  # what was in flight arrives
        count = len(probe.messages)
        time.sleep(0.3)
        assert len(probe.messages) == count, 'joint states while paused'
        reset = probe.node.create_client(Trigger, '/shaper_sim/reset')
        answer = probe.call(reset, Trigger.Request())
        assert answer.success and answer.message.startswith('reset: input angle 0 rad')
        assert probe.call(pause, SetBool.Request(data=False)).message == 'running'
        probe.wait_for(lambda: len(probe.messages) > count + 3, what='publishing again')
        # After the reset: the angle restarted from 0 at the speed in force.
        first = probe.messages[count]
        assert abs(first.position[0]) <= 5.0 * 0.05 and first.velocity[0] == 5.0
        assert math.isfinite(first.position[3])
    finally:
        code, output = node.stop()
    assert code == 0 and 'Traceback' not in output, output
