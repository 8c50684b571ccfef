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
The shaper_sim executable as its own process, over real DDS.

Parameters are changed through the node's parameter services (rcl_interfaces SetParameters,
what `ros2 param set` calls). Everything checked is derived here independently: the input
angle from the piecewise-linear speed profile, the offset from its rate limit, the other
joints from the kinematics core at the published angle, speed and offset.
"""

import math
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import state
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterValue
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.qos import qos_profile_parameters
from std_srvs.srv import SetBool, Trigger

from ros_probe import stamp_ns, stop_process
from shaper_process import NS, Process, Probe, wrapped

RATE = 100.0  # Hz, the default publish_rate
ACCELERATION_LIMIT = 20.0  # rad/s^2, config/shaper.yaml
OFFSET_RATE_LIMIT = 0.005  # m/s, config/shaper.yaml


@pytest.fixture
def probe():
    made = Probe()
    yield made
    made.close()


# name, value, text the reason must contain besides "<name> = <value!r> refused: ".
BAD_VALUES = [
    ('coupling_offset', 0.03, '[-0.0225, 0.0225] m'),
    ('coupling_offset', -0.024, '[-0.0225, 0.0225] m'),
    ('coupling_offset', math.nan, 'not finite'),
    ('coupling_offset', math.inf, 'not finite'),
    ('coupling_offset', 'far', 'floating-point'),
    ('coupling_offset', False, 'floating-point'),
    ('offset_rate_limit', 0.0, '[1e-06, 1] m/s'),
    ('offset_rate_limit', -0.5, '[1e-06, 1] m/s'),
    ('input_acceleration_limit', 0.0, '[0.001, 100000] rad/s^2'),
    ('input_speed', 60.5, '[-60, 60] rad/s'),
    ('input_speed', -math.inf, 'not finite'),
    ('max_input_speed', 1.0, 'below |input_speed| = 8 rad/s'),
    ('publish_rate', 1000.0, 'read-only'),
    ('pivot_distance', 0.04, 'crank_radius (0.0505 m) must be smaller than pivot_distance'),
    ('frame_id', '', 'non-empty string'),
]


def test_process_publishes_a_continuous_exact_state_and_refuses_bad_values(probe):
    node = Process('-p', 'input_speed:=4.0')
    try:
        probe.wait_for(lambda: len(probe.messages) >= 50, what='first joint states')
        assert probe.set_parameter('coupling_offset', 0.01).successful
        assert probe.set_parameter('input_speed', 8.0).successful
        refusals = {(name, repr(value)): probe.set_parameter(name, value)
                    for name, value, _ in BAD_VALUES}
        count = len(probe.messages)
        # The offset needs 2 s to travel 10 mm at 5 mm/s; keep going until it has arrived.
        probe.wait_for(lambda: len(probe.messages) > count + 30
                       and probe.messages[-1].position[4] == 0.01,
                       what='the offset to arrive and publishing to continue')
        values = probe.get_parameters([name for name, _, _ in BAD_VALUES])
        messages = list(probe.messages)
    finally:
        code, output = node.stop()
    assert code == 0 and 'Traceback' not in output, output

    for name, value, words in BAD_VALUES:
        result = refusals[(name, repr(value))]
        assert not result.successful, (name, value)
        assert result.reason.startswith(f'{name} = {value!r} refused: '), result.reason
        assert words in result.reason, result.reason
    assert values['coupling_offset'] == 0.01 and values['input_speed'] == 8.0
    assert values['publish_rate'] == RATE and values['frame_id'] == 'shaper_base'

    # Rate: every tick arrived, stamps strictly increasing, mean rate within 10 % (a loaded
    # two-core machine delays single ticks; the timer does not drift).
    stamps = [stamp_ns(m) for m in messages]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    rate = (len(stamps) - 1) / ((stamps[-1] - stamps[0]) / NS)
    gaps = np.diff(stamps) / NS
    assert rate == pytest.approx(RATE, rel=0.1), (
        f'{len(stamps)} messages, gaps: median {np.median(gaps):.4f} s, largest '
        f'{gaps.max():.4f} s, {np.count_nonzero(gaps > 1.5 / RATE)} over 1.5 periods')

    geometry = Geometry.paper()
    speeds_seen = set()
    for before, after in zip(messages, messages[1:]):
        dt = (stamp_ns(after) - stamp_ns(before)) / NS
        (angle0, *_, offset0), (angle1, *_, offset1) = before.position, after.position
        speed0, speed1 = before.velocity[0], after.velocity[0]
        speeds_seen.add(speed1)
        # Input angle: the exact integral of a speed that ramps at the limit (possibly
        # reaching its command inside the interval) -- up to float rounding.
        ramp_time = min(abs(speed1 - speed0) / ACCELERATION_LIMIT, dt)
        expected = 0.5 * (speed0 + speed1) * ramp_time + speed1 * (dt - ramp_time)
        assert abs(wrapped(angle1 - angle0 - expected)) < 1e-9
        # Offset: moves no faster than its rate limit.
        assert abs(offset1 - offset0) <= OFFSET_RATE_LIMIT * dt * (1 + 1e-9)
        # Every other joint is continuous: its move over the interval matches the
        # trapezoid of its published velocities within 5 % of the largest possible move per
        # period (a 1 mm offset step would jump the flywheel by 0.04 rad, about half a
        # tick's move). Smooth motion stays below that: the closed form at 8 rad/s and
        # 10 mm, one period apart, gives at most 4.7 %, next to a stroke reversal, and the
        # same per period over intervals of 1.5 to 5 periods, which a loaded machine's late
        # tick makes; so the allowance grows with the interval in periods.
        lateness = max(1.0, dt * RATE)
        for joint in (1, 2, 3):
            move = after.position[joint] - before.position[joint]
            if joint == 1:
                move = wrapped(move)
            fastest = max(abs(before.velocity[joint]), abs(after.velocity[joint]))
            trapezoid = 0.5 * (before.velocity[joint] + after.velocity[joint]) * dt
            assert abs(move - trapezoid) <= 0.05 * lateness * fastest * dt + 1e-12, (
                joint, dt, after)
    assert {4.0, 8.0} <= speeds_seen and len(speeds_seen) > 3  # ramped, not jumped

    # Published state = the core's closed form at the published angle, speed and offset.
    for message in messages:
        angle, flywheel, lever, ram, offset, radius = message.position
        speed, flywheel_speed, lever_speed, ram_velocity, offset_rate, _ = message.velocity
        assert radius == geometry.crank_radius
        assert all(map(math.isfinite, list(message.position) + list(message.velocity)))
        exact = state(geometry, offset, angle, speed, 0.0, offset_rate)
        assert abs(wrapped(flywheel - exact.flywheel_angle)) < 1e-12
        assert (lever, ram) == pytest.approx((exact.lever_angle, exact.ram_position),
                                             abs=1e-15)
        assert (flywheel_speed, lever_speed, ram_velocity) == pytest.approx(
            (exact.flywheel_speed, exact.lever_speed, exact.ram_velocity), rel=1e-12,
            abs=1e-15)


@pytest.mark.parametrize('executor', ['events', 'single'])
@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM],
                         ids=['SIGINT', 'SIGTERM'])
def test_process_stops_cleanly(probe, signal_number, executor):
    node = Process(environment={'QRM_ROS_EXECUTOR': executor})
    try:
        probe.wait_for(lambda: len(probe.messages) >= 3, what='first joint states')
    finally:
        code, output = node.stop(signal_number)
    assert code == 0, output
    assert 'Traceback' not in output, output


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM],
                         ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('delay', [0.4, 0.8])
def test_a_stop_while_starting_is_quiet(signal_number, delay):
    # Importing rclpy, numpy and scipy takes a while: a stop then exits quietly too.
    node = Process()
    time.sleep(delay)  # the moment under test: somewhere in start-up
    code, output = node.stop(signal_number)
    assert code == 0, output
    assert 'Traceback' not in output and 'KeyboardInterrupt' not in output, output


def test_process_refuses_a_bad_start_up_value_and_exits_2():
    node = Process('-p', 'coupling_offset:=0.024')
    code, output = node.stop(None, timeout=30.0)
    assert code == 2
    assert 'Traceback' not in output
    assert 'coupling_offset' in output and '0.024' in output and '[-0.0225, 0.0225]' in output


# Robustness: nothing a client sends stops the node ----------------------------------------

def test_malformed_and_bursty_requests_never_stop_the_node(probe):
    node = Process()
    try:
        probe.wait_for(lambda: len(probe.messages) >= 3, what='first joint states')
        malformed = ParameterMsg(name='coupling_offset', value=ParameterValue(type=99))
        result, = probe.call(probe.set_client, SetParameters.Request(
            parameters=[malformed])).results
        assert not result.successful
        assert 'coupling_offset: malformed request refused' in result.reason, result.reason
        atomic = probe.node.create_client(SetParametersAtomically,
                                          '/shaper_sim/set_parameters_atomically')
        result = probe.call(atomic, SetParametersAtomically.Request(
            parameters=[malformed])).result
        assert not result.successful and '99' in result.reason
        # A burst of service calls from clients with deep queues (as rclpy's parameter
        # clients have): every one is answered (the default service queue of 10 dropped all
        # but a few dozen of 600).
        pause = probe.node.create_client(SetBool, '/shaper_sim/pause',
                                         qos_profile=qos_profile_parameters)
        reset = probe.node.create_client(Trigger, '/shaper_sim/reset',
                                         qos_profile=qos_profile_parameters)
        assert pause.wait_for_service(10.0) and reset.wait_for_service(10.0)
        futures = [pause.call_async(SetBool.Request(data=i % 2 == 0)) for i in range(600)]
        futures += [reset.call_async(Trigger.Request()) for _ in range(600)]
        probe.wait_for(lambda: all(f.done() for f in futures), timeout=60.0,
                       what=f'1200 answers ({sum(f.done() for f in futures)} came)')
        assert all(f.result().success for f in futures)
        assert probe.set_parameter('coupling_offset', 0.002).successful
        count = len(probe.messages)
        probe.wait_for(lambda: len(probe.messages) > count + 3, what='publishing after it all')
    finally:
        code, output = node.stop()
    assert code == 0 and 'Traceback' not in output, output


@pytest.mark.parametrize('arguments, words', [
    (['-p', 'publish_rate:=0.5'], ['publish_rate = 0.5 refused', '[1, 10000] Hz']),
    (['-p', 'crank_phase:=4.0'], ['crank_phase = 4.0 refused', '[-3.14159, 3.14159] rad']),
    (['-p', 'ram_height:=-0.1'], ['ram_height', '-0.1', '> 0']),
    (['-p', 'marker_rate:=1.0e-310'],
     ['marker_rate = 1e-310 refused', '0 (off) or [0.01, 1000] Hz']),
    (['-p', 'coupling_offset'], ['cannot start', "parameter override rule: '-p"]),
    (['--params-file', '/nonexistent/shaper.yaml'], ['cannot start', 'params file']),
], ids=['publish_rate', 'crank_phase', 'geometry', 'tiny marker_rate', 'malformed -p',
        'missing params file'])
def test_start_up_problems_get_one_line_and_exit_2(arguments, words):
    code, output = Process(*arguments).stop(None, timeout=30.0)
    assert code == 2, output
    assert 'Traceback' not in output, output
    lines = [line for line in output.splitlines() if 'shaper_sim: cannot start' in line]
    assert len(lines) == 1, output
    for word in words:
        assert word in lines[0], output


def test_an_unknown_start_up_parameter_is_reported(probe):
    node = Process('-p', 'coupling_ofset:=0.01')
    try:
        probe.wait_for(lambda: len(probe.messages) >= 3, what='first joint states')
    finally:
        code, output = node.stop()
    assert code == 0, output
    assert 'coupling_ofset ignored' in output and 'did you mean coupling_offset' in output


STALLING_SUBSCRIBER = '''
import sys
import rclpy
from qrm_ros.node.process.ros_process import init_rclpy, spin_until_stopped, StopRequest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
init_rclpy()
node = Node('stalling_subscriber')
out = open(sys.argv[1], 'w', buffering=1)
node.create_subscription(
    JointState, 'joint_states',
    lambda m: out.write(f'{m.header.stamp.sec * 10**9 + m.header.stamp.nanosec}\\n'), 10000)
executor = SingleThreadedExecutor()
executor.add_node(node)
with StopRequest() as stop:
    spin_until_stopped(executor, stop)
'''


def test_a_subscriber_that_stalls_for_a_moment_loses_nothing(probe, tmp_path):
    # A reliable subscriber that stops for 0.5 s (a loaded machine) at 1 kHz gets every
    # message the node published, as a parallel subscriber (the probe) does. (Measured:
    # transport buffers carry stalls up to about 1 s whatever the publisher history; the
    # node keeps a second of history so that the writer can also resend what a transport
    # dropped.)
    node = Process('-p', 'publish_rate:=1000.0')
    received = tmp_path / 'stamps.txt'
    subscriber = subprocess.Popen([sys.executable, '-c', STALLING_SUBSCRIBER, str(received)])

    def seen():
        return received.read_text().split() if received.exists() else []
    try:
        probe.wait_for(lambda: len(seen()) >= 100, what='the subscriber receiving')
        subscriber.send_signal(signal.SIGSTOP)
        time.sleep(0.5)  # the stall under test
        subscriber.send_signal(signal.SIGCONT)
        count = len(seen())
        probe.wait_for(lambda: len(seen()) > count + 1000, what='the subscriber catching up')
    finally:
        subscriber.send_signal(signal.SIGCONT)
        stop_process(subscriber)
        code, output = node.stop()
    assert code == 0, output
    stamps = [int(s) for s in seen()]
    got = set(stamps)
    window = [stamp_ns(m) for m in probe.messages if stamps[0] <= stamp_ns(m) <= stamps[-1]]
    missing = [s for s in window if s not in got]
    assert not missing, f'{len(missing)} of {len(window)} messages lost by the stalled subscriber'
