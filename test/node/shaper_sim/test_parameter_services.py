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
The shaper_sim parameters through rclpy (qrm_ros.node.shaper_sim.parameter_services), in-process.

Declared with descriptors, every change judged by the rules of shaper_parameters before
rclpy's own checks, malformed requests answered, start-up values refused with a reason; and
the rclpy internals this relies on, so that an rclpy update that breaks one fails here.
"""

import math

import pytest
from qrm_ros.node.shaper_sim.parameter_services import start_up_overrides
from qrm_ros.node.shaper_sim.shaper_parameters import PARAMETERS
from qrm_ros.node.shaper_sim.shaper_sim import ShaperSimNode
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters
from rclpy.node import Node
from rclpy.parameter import Parameter

from ros_probe import call
from shaper_harness import H_PIVOT, R, R1


def test_parameters_are_declared_with_units_ranges_and_read_only_flags(harness):
    h = harness(spin_shaper=True)
    request = DescribeParameters.Request(names=list(PARAMETERS))
    descriptors = {d.name: d for d in h.call(
        DescribeParameters, '/shaper_sim/describe_parameters', request).descriptors}
    read_only = {name for name, d in descriptors.items() if d.read_only}
    assert read_only == {'coupling_radius', 'crank_radius', 'pivot_distance', 'ram_height',
                         'crank_phase', 'publish_rate', 'max_crank_radius'}
    for name, spec in PARAMETERS.items():
        assert f'[{spec.unit}]' in descriptors[name].description or not spec.unit
        assert descriptors[name].additional_constraints.startswith('allowed: ')
    offset_range = descriptors['coupling_offset'].floating_point_range[0]
    # 0.9 r1, shown as 0.0225 (not 0.022500000000000003) in descriptors and messages.
    assert (offset_range.from_value, offset_range.to_value) == (-0.0225, 0.0225)
    assert descriptors['frame_id'].type == ParameterType.PARAMETER_STRING
    defaults = {name: h.shaper.get_parameter(name).value for name in PARAMETERS}
    assert defaults == {name: spec.default for name, spec in PARAMETERS.items()}
    assert (defaults['coupling_radius'], defaults['crank_radius'],
            defaults['pivot_distance']) == (R1, R, H_PIVOT)


# name, value, words every reason must contain (besides the name and the value's repr).
REFUSALS = [
    ('coupling_offset', 0.03, ['[-0.0225, 0.0225] m', 'max_safe_offset']),
    ('coupling_offset', -0.0230, ['[-0.0225, 0.0225] m']),
    ('coupling_offset', 0.025, ['[-0.0225, 0.0225] m']),
    ('coupling_offset', math.nan, ['not finite', '[-0.0225, 0.0225] m']),
    ('coupling_offset', math.inf, ['not finite']),
    ('coupling_offset', 'abc', ['floating-point', '[-0.0225, 0.0225] m']),
    ('coupling_offset', True, ['floating-point']),
    ('coupling_offset', [0.01], ['floating-point']),
    ('offset_rate_limit', 0.0, ['[1e-06, 1] m/s']),
    ('offset_rate_limit', -0.001, ['[1e-06, 1] m/s']),
    ('input_acceleration_limit', 0.0, ['[0.001, 100000] rad/s^2']),
    ('input_acceleration_limit', -math.inf, ['not finite']),
    ('input_speed', 61.0, ['[-60, 60] rad/s', 'max_input_speed']),
    ('input_speed', -math.inf, ['not finite']),
    ('max_input_speed', 0.0, ['[0.001, 10000] rad/s']),
    ('max_input_speed', 5.0, ['below |input_speed| = 6.28319 rad/s']),
    ('publish_rate', 50.0, ['read-only', 'it stays 100.0']),
    ('crank_radius', 0.2, ['read-only', 'must be smaller than pivot_distance']),
    ('coupling_radius', 0.03, ['read-only']),
    ('frame_id', '', ['non-empty string']),
    ('frame_id', 3.0, ['non-empty string']),
    # Finite but absurd: every value has a bound no shaper leaves (core.dynamics.physical_ranges).
    ('frame_id', 'ab\x00cd', ['without control characters']),
    ('lever_mass', 1e308, ['<= 10000 kg']),
    ('gravity', 1e308, ['<= 100 m/s^2']),
    ('lever_com_distance', 1e308, ['[-10, 10] m']),
    ('lever_inertia', 1e308, ['<= 10000 kg*m^2']),
    ('input_inertia', 1e308, ['<= 10000 kg*m^2']),
    ('ram_mass', 1e308, ['<= 10000 kg']),
    ('ram_friction', 1e308, ['<= 1e+06 N']),
    ('cutting_force', 1e308, ['<= 1e+06 N']),
    ('motor_max_torque', 1e308, ['<= 1e+06 N*m']),
    ('motor_speed_stiffness', 1e12, ['<= 1e+06 N*m*s/rad']),
    ('motor_speed_stiffness', 1e6, ["the motor drive's time constant", 'below 1e-05 s']),
    ('motor_max_torque', 1e-12, ['the motor saturates within', 'below 1e-06 rad/s']),
    ('cutting_speed_target', 1e308, ['<= 100 m/s']),
    ('marker_rate', 5e-324, ['0 (off) or [0.01, 1000] Hz']),
    ('marker_rate', 1e-310, ['0 (off) or [0.01, 1000] Hz']),
]


@pytest.mark.parametrize('name, value, words', REFUSALS,
                         ids=[f'{n}={v!r}' for n, v, _ in REFUSALS])
def test_bad_values_are_refused_with_a_reason_and_change_nothing(harness, name, value, words):
    h = harness(spin_shaper=False)
    before = {n: h.shaper.get_parameter(n).value for n in PARAMETERS}
    commands = (h.shaper.stepper.speed_command, h.shaper.stepper.offset_command)
    result, = h.shaper.set_parameters([Parameter(name, value=value)])
    assert not result.successful
    assert result.reason.startswith(f'{name} = {value!r} refused: ')
    for word in words:
        assert word in result.reason
    assert {n: h.shaper.get_parameter(n).value for n in PARAMETERS} == before
    assert (h.shaper.stepper.speed_command, h.shaper.stepper.offset_command) == commands


def test_inertia_too_small_for_the_motor_is_refused_as_a_whole(harness):
    # Each value alone is fine; together the motor's time constant is 3.5e-7 s.
    h = harness(spin_shaper=False)
    result = h.shaper.set_parameters_atomically([Parameter('input_inertia', value=1e-4),
                                                 Parameter('flywheel_inertia', value=1e-4)])
    assert not result.successful
    assert "the motor drive's time constant" in result.reason and '1e-05 s' in result.reason
    assert h.shaper.get_parameter('input_inertia').value == 1.2


def test_an_undeclared_name_is_refused_naming_it(harness):
    h = harness(spin_shaper=False)
    result, = h.shaper.set_parameters([Parameter('coupling_ofset', value=0.01)])
    assert not result.successful
    assert result.reason.startswith('coupling_ofset: no such parameter of shaper_sim')
    assert 'coupling_offset' in result.reason
    assert not h.shaper.has_parameter('coupling_ofset')


def test_the_on_set_callback_refuses_too(harness):
    # rclpy's own path (descriptor checks, then on-set callbacks) without this node's
    # front check: cross-parameter rules still refuse, with the same reason.
    h = harness(spin_shaper=False)
    result = Node.set_parameters_atomically(h.shaper, [Parameter('input_speed', value=70.0)])
    assert not result.successful and 'input_speed = 70.0 refused' in result.reason
    assert h.shaper.get_parameter('input_speed').value == 2 * math.pi


def test_accepted_values_reach_the_stepper(harness):
    h = harness(spin_shaper=False)
    results = h.shaper.set_parameters([
        Parameter('coupling_offset', value=0.0225), Parameter('input_speed', value=-3),
        Parameter('offset_rate_limit', value=0.01),
        Parameter('input_acceleration_limit', value=50.0),
        Parameter('frame_id', value='shaper_table')])
    assert all(r.successful for r in results), [r.reason for r in results]
    stepper = h.shaper.stepper
    assert (stepper.offset_command, stepper.speed_command) == (0.0225, -3.0)
    assert (stepper.offset_rate_limit, stepper.input_acceleration_limit) == (0.01, 50.0)
    # An integer for a double parameter is taken as that double (`ros2 param set ... 0`).
    assert h.shaper.get_parameter('input_speed').type_ == Parameter.Type.DOUBLE
    # Raising the limit and the speed together is one consistent change.
    result = h.shaper.set_parameters_atomically([Parameter('max_input_speed', value=100.0),
                                                 Parameter('input_speed', value=90.0)])
    assert result.successful, result.reason
    assert stepper.speed_command == 90.0


def test_a_consistent_atomic_change_is_judged_as_a_whole(harness):
    h = harness(spin_shaper=False, input_speed=50.0)
    # Lowering the limit below today's command is fine when the same change lowers the
    # command: the cross-check sees every value after the change.
    result = h.shaper.set_parameters_atomically([Parameter('input_speed', value=5.0),
                                                 Parameter('max_input_speed', value=10.0)])
    assert result.successful, result.reason
    assert h.shaper.stepper.speed_command == 5.0
    result = h.shaper.set_parameters_atomically([Parameter('max_input_speed', value=4.0),
                                                 Parameter('input_speed', value=4.5)])
    assert not result.successful and 'below |input_speed| = 4.5 rad/s' in result.reason


def test_the_rclpy_internals_this_node_relies_on_still_work(harness):
    # parameter_services.py isolates three uses of rclpy internals; an rclpy update breaking one
    # must fail here, not in a user's hands.
    h = harness(spin_shaper=True, coupling_offset=0.004)
    # 1. The start-up overrides are where the node finds a refused or unknown value.
    assert start_up_overrides(h.shaper)['coupling_offset'].value == 0.004
    # 2. The parameter services' callbacks are replaced: a malformed type gets a reason.
    client = h.probe.create_client(SetParameters, '/shaper_sim/set_parameters')
    malformed = ParameterMsg(name='input_speed', value=ParameterValue(type=42))
    result, = call(client, SetParameters.Request(parameters=[malformed])).results
    assert not result.successful and 'input_speed: malformed request refused' in result.reason
    # 3. rclpy's own set path (pre-set callback) takes an integer for a double.
    assert Node.set_parameters_atomically(
        h.shaper, [Parameter('input_speed', value=3)]).successful
    assert h.shaper.get_parameter('input_speed').type_ == Parameter.Type.DOUBLE
    assert h.shaper.stepper.speed_command == 3.0


def test_bad_start_up_values_are_refused_with_a_reason(context):
    for overrides, words in [
            ({'coupling_offset': 0.024}, ['coupling_offset = 0.024 refused',
                                          '[-0.0225, 0.0225]']),
            ({'crank_radius': 0.12}, ['crank_radius', '0.12', 'pivot_distance']),
            ({'input_speed': 80.0}, ['input_speed = 80.0 refused', '[-60, 60]']),
            ({'offset_rate_limit': -1.0}, ['offset_rate_limit = -1.0 refused', '[1e-06, 1]']),
            ({'publish_rate': 100}, ['publish_rate = 100 refused', 'decimal point',
                                     'e.g. 100.0'])]:
        with pytest.raises(ValueError) as error:
            ShaperSimNode(context=context, parameter_overrides=[
                Parameter(name, value=value) for name, value in overrides.items()])
        for word in words:
            assert word in str(error.value)
        assert 'Invalid parameter' not in str(error.value)  # this node's words, not rclpy's
