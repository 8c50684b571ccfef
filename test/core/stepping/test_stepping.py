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
ShaperStepper against independent closed forms (ROS-free).

References here never call the stepper's integration: constant speed uses exact rational
arithmetic, ramps use the textbook formulas theta = w0 t + a t^2 / 2 and
delta = delta0 + rate t, and derivatives are checked with finite differences.
"""

from fractions import Fraction
import math
import random

import pytest
from qrm_ros.core.kinematics.geometry import Geometry, KinematicsError
from qrm_ros.core.kinematics import state
from qrm_ros.core.stepping.stepping import ShaperStepper, wrap_angle

GEOMETRY = Geometry.paper()
# pi to 50 digits, for the exact reference of a wrapped angle.
PI = Fraction('3.14159265358979323846264338327950288419716939937510')
NS = 1_000_000_000


def stepper(input_speed=2.0, offset=0.0, acceleration=20.0, rate=0.005):
    return ShaperStepper(GEOMETRY, input_speed, offset, acceleration, rate)


def angle_error(a, b):
    """Difference of two angles modulo 2 pi, in [-pi, pi)."""
    return wrap_angle(a - b)


def exact_wrapped(value):
    """Wrap an exact rational angle into [-pi, pi) with 50-digit pi; return a float."""
    turns = math.floor((value + PI) / (2 * PI))
    return float(value - turns * 2 * PI)


def jittered_stamps(start_ns, period_ns, count, seed):
    rng = random.Random(seed)
    stamps, now = [], start_ns
    for _ in range(count):
        now += period_ns + rng.randint(-period_ns // 3, period_ns // 3)
        stamps.append(now)
    return stamps


def test_wrap_angle_is_half_open_and_removes_whole_turns():
    # The double pi is 1.2e-16 below pi, so math.pi lies inside [-pi, pi); in doubles the
    # result is kept in [-math.pi, math.pi), which moves such an edge value by one last bit.
    assert wrap_angle(-math.pi) == -math.pi
    assert wrap_angle(0.0) == 0.0
    assert wrap_angle(1.0) == 1.0
    for value in [math.pi, 3 * math.pi, -3 * math.pi + 1e-9, 1e6, -1e6, 123.456,
                  2 * math.pi - 1e-17, -math.nextafter(math.pi, 4.0)]:
        wrapped = wrap_angle(value)
        assert -math.pi <= wrapped < math.pi
        exact = exact_wrapped(Fraction(value))
        assert abs(angle_error(wrapped, exact)) <= 4 * 2.0 ** -52 * max(1.0, abs(value))


def test_constant_speed_one_hour_at_60_rad_s_keeps_full_precision():
    # One hour at 100 Hz with jittered stamps at today's epoch: the wrapped angle must equal
    # speed * elapsed time (exact rational arithmetic, 50-digit pi) to within the
    # rounding of the additions, which wrapping keeps at the size of pi's last bit.
    speed = 60.0
    s = stepper(input_speed=speed)
    start = 1_770_000_000 * NS
    s.integrate_to(start)
    stamps = jittered_stamps(start, 10_000_000, 360_000, seed=1)
    for stamp in stamps:
        s.integrate_to(stamp)
        assert -math.pi <= s.input_angle < math.pi
    exact = exact_wrapped(Fraction(speed) * Fraction(stamps[-1] - start, NS))
    # Per step: one rounding of dt, of the product, of the sum (<= 2^-52 * pi each) and of
    # the turn removal; 360 000 steps bound the drift by about 1e-10 rad.
    bound = len(stamps) * 4 * math.pi * 2.0 ** -52
    assert abs(angle_error(s.input_angle, exact)) < bound
    assert s.input_speed == speed
    assert s.input_acceleration == 0.0


def ramp_reference(start_speed, target, acceleration, t):
    """Angle and speed t seconds after a ramp from start_speed toward target begins."""
    ramp_time = abs(target - start_speed) / acceleration
    direction = math.copysign(1.0, target - start_speed)
    if t <= ramp_time:
        return start_speed * t + 0.5 * direction * acceleration * t * t, \
            start_speed + direction * acceleration * t
    angle = start_speed * ramp_time + 0.5 * direction * acceleration * ramp_time ** 2
    return angle + target * (t - ramp_time), target


@pytest.mark.parametrize('start_speed, target', [(2.0, 10.0), (5.0, -5.0), (-3.0, -0.5)])
def test_speed_ramp_integrates_exactly(start_speed, target):
    acceleration = 20.0
    s = stepper(input_speed=start_speed, acceleration=acceleration)
    start = 5 * NS
    s.integrate_to(start)
    s.set_speed_command(target)
    ramp_time = abs(target - start_speed) / acceleration
    for stamp in jittered_stamps(start, 7_300_000, 150, seed=2):
        s.integrate_to(stamp)
        t = (stamp - start) / NS
        angle, speed = ramp_reference(start_speed, target, acceleration, t)
        assert abs(angle_error(s.input_angle, angle)) < 1e-12
        assert s.input_speed == pytest.approx(speed, abs=1e-12)
        expected_acceleration = math.copysign(acceleration, target - start_speed)
        assert s.input_acceleration == (expected_acceleration if t < ramp_time - 1e-12
                                        else 0.0)
    assert s.input_speed == target  # reached exactly, no overshoot


def test_offset_moves_at_its_rate_limit_and_stops_exactly_on_the_command():
    rate = 0.005
    s = stepper(offset=0.0, rate=rate)
    s.integrate_to(NS)
    s.set_offset_command(0.01)
    previous = 0.0
    stamps = jittered_stamps(NS, 10_000_000, 300, seed=3)
    last = NS
    for stamp in stamps:
        s.integrate_to(stamp)
        t = (stamp - NS) / NS
        assert s.offset == pytest.approx(min(rate * t, 0.01), abs=1e-15)
        assert abs(s.offset - previous) <= rate * (stamp - last) / NS * (1 + 1e-12)
        assert s.offset_rate == (rate if s.offset < 0.01 else 0.0)
        previous, last = s.offset, stamp
    assert s.offset == 0.01 and s.offset_rate == 0.0
    # Reversing the command moves back through zero at the same rate.
    s.set_offset_command(-0.01)
    s.integrate_to(last + 3 * NS)
    assert s.offset == pytest.approx(0.01 - 3 * rate, abs=1e-15)
    assert s.offset_rate == -rate


def test_command_takes_effect_from_the_last_step():
    s = stepper(input_speed=2.0)
    s.integrate_to(0)
    s.integrate_to(NS // 2)  # 1 rad at 2 rad/s
    s.set_speed_command(4.0)
    s.integrate_to(NS)  # ramps 0.1 s at 20 rad/s^2 from 0.5 s, then holds 4 rad/s
    angle = 1.0 + ramp_reference(2.0, 4.0, 20.0, 0.5)[0]
    assert abs(angle_error(s.input_angle, angle)) < 1e-13


def run_schedule(stamps, commands):
    """Step through stamps; commands {stamp: (speed, offset)} act from that stamp on."""
    s = stepper(input_speed=3.0, offset=-0.005)
    outputs = []
    for stamp in stamps:
        sample = s.advance_to(stamp)
        outputs.append((s.input_angle, s.input_speed, s.input_acceleration, s.offset,
                        s.offset_rate) + tuple(sample))
        if stamp in commands:
            speed, offset = commands[stamp]
            s.set_speed_command(speed)
            s.set_offset_command(offset)
    return s, outputs


def test_same_commands_at_same_stamps_are_bit_identical():
    stamps = jittered_stamps(1_700_000_000 * NS, 10_000_000, 2000, seed=4)
    commands = {stamps[100]: (9.0, 0.012), stamps[900]: (-4.0, -0.02),
                stamps[1500]: (1.0, 0.0)}
    _, first = run_schedule(stamps, commands)
    _, second = run_schedule(stamps, commands)
    assert [[v.hex() for v in row] for row in first] == [[v.hex() for v in row]
                                                         for row in second]


def test_result_does_not_depend_on_how_time_is_sliced():
    # Exact integration: a coarse and a fine tick pattern sharing the command stamps reach
    # the same state at a common stamp, up to rounding.
    fine = list(range(NS, 9 * NS, 1_000_000))
    coarse = [stamp for stamp in fine if stamp % 37_000_000 == 0 or stamp % NS == 0]
    commands = {2 * NS: (9.0, 0.012), 4 * NS: (-4.0, -0.02), 6 * NS: (1.0, 0.0)}
    fine_stepper, _ = run_schedule(fine + [9 * NS], commands)
    coarse_stepper, _ = run_schedule(coarse + [9 * NS], commands)
    assert abs(angle_error(fine_stepper.input_angle, coarse_stepper.input_angle)) < 1e-11
    assert fine_stepper.input_speed == coarse_stepper.input_speed
    assert fine_stepper.offset == pytest.approx(coarse_stepper.offset, abs=1e-16)


def unwrapped_difference(a, b):
    return angle_error(a, b)


def test_published_rates_are_the_derivatives_of_the_positions():
    # Offset moving and shaft accelerating at once: central differences of the returned
    # positions (h = 10 us) must match the returned rates (error ~ h^2 * third derivative).
    h = 10_000
    samples = {}
    for delta in (-h, 0, h):
        s = stepper(input_speed=3.0, offset=0.002, acceleration=20.0, rate=0.005)
        s.integrate_to(0)
        s.set_speed_command(10.0)
        s.set_offset_command(0.015)
        samples[delta] = (s.advance_to(200_000_000 + delta), s)
    (before, _), (middle, s), (after, _) = samples[-h], samples[0], samples[h]
    dt = 2 * h / NS
    assert s.input_acceleration == 20.0 and s.offset_rate == 0.005
    flywheel = unwrapped_difference(after.flywheel_angle, before.flywheel_angle) / dt
    assert flywheel == pytest.approx(middle.flywheel_speed, rel=1e-7)
    assert (after.lever_angle - before.lever_angle) / dt == pytest.approx(
        middle.lever_speed, rel=1e-7)
    assert (after.ram_position - before.ram_position) / dt == pytest.approx(
        middle.ram_velocity, rel=1e-7)
    assert (after.ram_velocity - before.ram_velocity) / dt == pytest.approx(
        middle.ram_acceleration, rel=1e-6)
    # And the returned state is the core's at the stepped angle, speed and offset.
    assert tuple(middle) == tuple(state(GEOMETRY, s.offset, s.input_angle, s.input_speed,
                                        20.0, 0.005))


def test_time_going_back_holds_the_state_and_restarts_the_time_base():
    s = stepper(input_speed=2.0)
    s.integrate_to(10 * NS)
    s.integrate_to(11 * NS)
    held = s.input_angle
    assert held == pytest.approx(2.0)
    s.integrate_to(3 * NS)  # simulated clock restarted
    assert s.time_resets == 1 and s.input_angle == held and s.stamp_ns == 3 * NS
    s.integrate_to(3 * NS + NS // 4)
    assert s.input_angle == pytest.approx(held + 0.5, abs=1e-15)


def test_reset_and_resync():
    s = stepper(input_speed=2.0, offset=0.0)
    s.integrate_to(0)
    s.set_speed_command(5.0)
    s.set_offset_command(0.01)
    s.integrate_to(NS)
    s.reset(-1.5, 0.004)
    assert (s.input_angle, s.input_speed, s.speed_command, s.offset, s.offset_command) == (
        0.0, -1.5, -1.5, 0.004, 0.004)
    sample = s.advance_to(7 * NS)  # new time base: nothing integrated
    assert s.input_angle == 0.0 and sample == state(GEOMETRY, 0.004, 0.0, -1.5)
    s.integrate_to(8 * NS)
    assert s.input_angle == pytest.approx(-1.5)
    s.resync()
    s.integrate_to(100 * NS)  # a pause: the 92 s in between do not count
    assert s.input_angle == pytest.approx(-1.5)


@pytest.mark.parametrize('call, value', [
    ('set_offset_command', 0.025), ('set_offset_command', -0.03),
    ('set_offset_command', float('nan')), ('set_speed_command', float('inf')),
    ('set_speed_command', 'fast'), ('set_speed_command', None),
])
def test_bad_commands_are_refused_and_change_nothing(call, value):
    s = stepper()
    before = (s.speed_command, s.offset_command)
    with pytest.raises(KinematicsError):
        getattr(s, call)(value)
    assert (s.speed_command, s.offset_command) == before


@pytest.mark.parametrize('limits', [
    {'input_acceleration_limit': 0.0}, {'offset_rate_limit': -1.0},
    {'offset_rate_limit': float('inf')}, {'input_acceleration_limit': float('nan')},
    {'input_acceleration_limit': 1.0, 'offset_rate_limit': 0.0},
])
def test_bad_limits_are_refused_and_change_nothing(limits):
    s = stepper(acceleration=20.0, rate=0.005)
    with pytest.raises(KinematicsError, match='must be'):
        s.set_limits(**limits)
    assert (s.input_acceleration_limit, s.offset_rate_limit) == (20.0, 0.005)
