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
The shaper_sim node in-process, over real rclpy and DDS (no mocks).

The published state is checked through ShaperSimNode.publish_at with synthetic stamps (the
timer does exactly that with the node clock), so those checks are deterministic and fast;
services, pause and simulated time go through a spinning executor. The parameters, the
stroke-pair reports and the markers have test files of their own.
"""

import math
import time

import pytest
from qrm_ros.core.kinematics import state
from qrm_ros.core.common.names import PUBLISHED_JOINT_NAMES
import rclpy
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from ros_probe import stamp_ns
from shaper_harness import NS, run_ticks


# Publishing -------------------------------------------------------------------------------

def test_published_state_is_the_core_closed_form_at_the_stamp(harness):
    h = harness(spin_shaper=False, coupling_offset=0.005)
    h.shaper.set_parameters([Parameter('coupling_offset', value=0.012),
                             Parameter('input_speed', value=9.0)])
    stamps = run_ticks(h.shaper, 77 * NS, 1.0)
    h.wait_for(lambda: len(h.joint_states) == len(stamps), what='every joint state')
    geometry = h.shaper.geometry
    for message, stamp in zip(h.joint_states, stamps):
        assert list(message.name) == list(PUBLISHED_JOINT_NAMES)
        assert stamp_ns(message) == stamp
        assert message.header.frame_id == 'shaper_base'
        angle, flywheel, lever, ram, offset, radius = message.position
        speed, flywheel_speed, lever_speed, ram_velocity, offset_rate, radius_rate = \
            message.velocity
        assert (radius, radius_rate) == (geometry.crank_radius, 0.0)  # the stroke held
        expected = state(geometry, offset, angle, speed, 0.0, offset_rate)
        assert -math.pi <= angle < math.pi and -math.pi <= flywheel < math.pi
        assert math.remainder(flywheel - expected.flywheel_angle, 2 * math.pi) == \
            pytest.approx(0.0, abs=1e-12)
        assert (lever, ram) == pytest.approx((expected.lever_angle, expected.ram_position),
                                             abs=1e-15)
        assert (flywheel_speed, lever_speed, ram_velocity) == pytest.approx(
            (expected.flywheel_speed, expected.lever_speed, expected.ram_velocity),
            rel=1e-12, abs=1e-15)


def test_time_going_back_is_survived(harness):
    h = harness(spin_shaper=False)
    run_ticks(h.shaper, 100 * NS, 0.5)
    held = h.shaper.stepper.input_angle
    assert h.shaper.publish_at(3 * NS)  # simulated clock restarted
    assert h.shaper.stepper.input_angle == held and h.shaper.stepper.time_resets == 1
    assert not h.shaper.publish_at(3 * NS)  # a repeated stamp is not republished
    assert not h.shaper.publish_at(0)  # simulated time not started yet


# Services, pause, topic command, simulated time ---------------------------------------------

def test_pause_holds_and_resume_continues_from_the_held_state(harness):
    h = harness()
    arrays = []
    h.probe.create_subscription(MarkerArray, 'linkage_markers', arrays.append, 100)
    h.wait_for(lambda: len(h.joint_states) >= 5, what='joint states')
    response = h.call(SetBool, '/shaper_sim/pause', SetBool.Request(data=True))
    assert response.success and response.message == 'paused'
    count = len(h.joint_states)
    held = h.shaper.stepper.input_angle
    drawn = len(arrays)
    time.sleep(0.2)  # would be 20 ticks
    assert len(h.joint_states) == count and h.shaper.stepper.input_angle == held
    # The held state is still drawn (for a viewer that starts during the pause).
    h.wait_for(lambda: len(arrays) >= drawn + 3, what='markers while paused')
    stamp = h.joint_states[-1].header.stamp
    assert all(array.markers[0].header.stamp == stamp for array in arrays[drawn + 1:])
    assert h.call(SetBool, '/shaper_sim/pause', SetBool.Request(data=False)).success
    h.wait_for(lambda: len(h.joint_states) > count + 2, what='joint states after resuming')
    resumed = h.joint_states[count]
    assert resumed.position[0] == held  # the pause's 0.2 s do not count


def test_reset_returns_to_the_parameters(harness):
    h = harness(coupling_offset=0.004)
    h.wait_for(lambda: len(h.joint_states) >= 3, what='joint states')
    h.shaper.set_parameters([Parameter('input_speed', value=3.0)])
    response = h.call(Trigger, '/shaper_sim/reset', Trigger.Request())
    assert response.success and 'input speed 3.0 rad/s' in response.message
    # The first sample after the reset has angle 0 at speed 3 (the start had 2 pi rad/s).
    h.wait_for(lambda: any(m.velocity[0] == 3.0 for m in h.joint_states),
               what='joint states after reset')
    first = next(m for m in h.joint_states if m.velocity[0] == 3.0)
    assert first.position[0] == 0.0 and first.position[4] == 0.004


def test_speed_command_topic_accepts_good_values_and_ignores_bad_ones(harness):
    h = harness(spin_shaper=True)
    publisher = h.probe.create_publisher(Float64, 'input_speed_cmd', 10)
    h.wait_for(lambda: publisher.get_subscription_count() > 0, what='subscriber')
    for bad in (math.nan, math.inf, -61.0):
        publisher.publish(Float64(data=bad))
    publisher.publish(Float64(data=-12.5))
    h.wait_for(lambda: h.shaper.stepper.speed_command == -12.5, what='speed command')
    for bad in (math.nan, 1e9):
        publisher.publish(Float64(data=bad))
    count = len(h.joint_states)
    h.wait_for(lambda: len(h.joint_states) > count + 3, what='more joint states')
    assert h.shaper.stepper.speed_command == -12.5
    # The limit may not drop below the command in force.
    result, = h.shaper.set_parameters([Parameter('max_input_speed', value=10.0)])
    assert not result.successful and 'speed command in force' in result.reason


def test_use_sim_time_stamps_follow_clock(harness):
    h = harness(use_sim_time=True)
    clock = h.probe.create_publisher(Clock, '/clock', 10)
    start = 1234 * NS
    published = []
    deadline = time.monotonic() + 10.0
    stamp = start
    while len(h.joint_states) < 20 and time.monotonic() < deadline:
        stamp += 10_000_000
        clock.publish(Clock(clock=rclpy.time.Time(nanoseconds=stamp).to_msg()))
        published.append(stamp)
        time.sleep(0.002)
    assert len(h.joint_states) >= 20, 'no joint states on simulated time'
    stamps = [stamp_ns(m) for m in h.joint_states]
    assert all(s in published for s in stamps)
    assert stamps == sorted(stamps)


# Efforts ----------------------------------------------------------------------------------

def test_published_efforts_balance_the_energy(harness):
    # Power in at the input shaft = d(kinetic + potential energy)/dt - (load force x ram
    # velocity), with every term from the published joint values and the mass parameters
    # (doc/dynamics.md), the derivative by central differences at 10 kHz.
    mass = dict(input_inertia=0.01, flywheel_inertia=0.5, lever_inertia=0.3, lever_mass=8.0,
                lever_com_distance=0.15, ram_mass=20.0, gravity=9.81)
    h = harness(spin_shaper=False, coupling_offset=0.01, input_speed=4.0, cutting_force=500.0,
                ram_friction=30.0, cutting_length=0.15, **mass)
    rate = 10000.0
    stamps = [5 * NS + i * 100_000 for i in range(1, int(1.3 * rate))]
    for index, stamp in enumerate(stamps, 1):
        assert h.shaper.publish_at(stamp)
        if index % 500 == 0 or index == len(stamps):  # within the probe's queue
            h.wait_for(lambda: len(h.joint_states) == index, what='every joint state')

    def energy(message):
        angle, flywheel, lever, ram, offset, _ = message.position
        speed, flywheel_speed, lever_speed, ram_velocity, _, _ = message.velocity
        kinetic = 0.5 * (mass['input_inertia'] * speed ** 2
                         + mass['flywheel_inertia'] * flywheel_speed ** 2
                         + mass['lever_inertia'] * lever_speed ** 2
                         + mass['ram_mass'] * ram_velocity ** 2)
        return kinetic + mass['lever_mass'] * mass['gravity'] * mass['lever_com_distance'] * \
            math.cos(lever)

    def load(message):
        ram, velocity = message.position[3], message.velocity[3]
        cutting = 500.0 if velocity < 0.0 and abs(ram) <= 0.075 else 0.0
        return cutting - math.copysign(30.0, velocity)

    checked = 0
    for before, middle, after in zip(h.joint_states, h.joint_states[1:], h.joint_states[2:]):
        assert len(middle.effort) == 6 and all(map(math.isfinite, middle.effort))
        if len({load(before), load(middle), load(after)}) > 1:
            continue  # a load switch between the samples: no smooth derivative there
        energy_rate = (energy(after) - energy(before)) * rate / 2
        power_in = middle.effort[0] * middle.velocity[0]
        load_power = load(middle) * middle.velocity[3]
        assert power_in == pytest.approx(energy_rate - load_power,
                                         abs=1e-4 * (1.0 + abs(power_in))), middle
        checked += 1
    assert checked > 0.95 * len(stamps)


def test_one_sample_efforts_equal_the_vectorised_ones():
    # The node's per-tick path (floats, math functions) and the array path agree.
    from qrm_ros.core.dynamics.chain import efforts, MassProperties
    from qrm_ros.core.kinematics.geometry import Geometry
    import numpy as np
    geometry, mass = Geometry.paper(), MassProperties.small_shaper()
    angles = np.linspace(-3.0, 3.0, 13)
    vectorised = efforts(geometry, mass, 0.013, angles, 5.0, 2.0, 0.004, 0.0, 300.0)
    for index, angle in enumerate(angles):
        one = efforts(geometry, mass, 0.013, float(angle), 5.0, 2.0, 0.004, 0.0, 300.0)
        assert one == pytest.approx([v[index] for v in vectorised], rel=1e-13, abs=1e-12)
