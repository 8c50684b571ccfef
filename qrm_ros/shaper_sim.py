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
The shaper_sim node: the mechanism stepped in time, published as joint states.

A thin adapter: ShaperStepper (qrm_ros.stepping) integrates the input angle and moves the
offset; the kinematics core gives every other state in closed form; find_stroke_pairs
(qrm_ros.strokes) measures each completed stroke pair for /diagnostics. This module only
declares and checks parameters, turns commands into stepper calls and states into messages.
"""

from array import array
import math
import sys
from typing import NamedTuple, Optional

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped
from qrm_ros.names import (DIAGNOSTICS_TOPIC, JOINT_NAMES, JOINT_STATES_TOPIC,
                           RAM_TWIST_TOPIC, SIM_NODE_NAME, SPEED_COMMAND_TOPIC,
                           STROKE_PAIR_STATUS)
from qrm_ros.kinematics import Geometry, KinematicsError, steady_theory
from qrm_ros.ros_process import (init_rclpy, RCLError, rcl_error_text, spin_until_stopped,
                                 StopRequest)
from qrm_ros.stepping import ShaperStepper, wrap_angle
from qrm_ros.strokes import find_stroke_pairs
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

__all__ = ['JOINT_NAMES', 'PARAMETERS', 'ShaperSimNode', 'main', 'refusal_reason']

GEOMETRY_NAMES = Geometry.field_names()
# At most this many tick samples wait in the diagnostics buffer for a stroke pair to end
# (at 100 Hz, 43 minutes; a shaft slower than one turn in that time gets no diagnostics).
DIAGNOSTICS_BUFFER_LIMIT = 2 ** 18
_WARNING_PERIOD = 1.0  # s, throttle for repeated warnings
_PAPER = Geometry.paper()


class ParameterSpec(NamedTuple):
    """One parameter's default, unit, meaning and allowed values (bounds inclusive)."""

    default: object
    unit: str
    description: str
    read_only: bool
    low: Optional[float] = None
    high: Optional[float] = None


PARAMETERS = {
    'coupling_radius': ParameterSpec(
        _PAPER.coupling_radius, 'm', 'Coupling crank radius r1: radius of the input pin in '
        'the yoke coupling. > 0. Structural: set at start-up only.', True),
    'crank_radius': ParameterSpec(
        _PAPER.crank_radius, 'm', 'Crank radius r on the flywheel (sets the ram stroke). '
        '0 < crank_radius < pivot_distance. Structural: set at start-up only.', True),
    'pivot_distance': ParameterSpec(
        _PAPER.pivot_distance, 'm', 'Distance h from the flywheel centre down to the lever '
        'pivot. > crank_radius. Structural: set at start-up only.', True),
    'ram_height': ParameterSpec(
        _PAPER.ram_height, 'm', 'Height H of the ram line above the lever pivot: ram '
        'position = H tan(lever angle). > 0. Structural: set at start-up only.', True),
    'crank_phase': ParameterSpec(
        _PAPER.crank_phase, 'rad', 'Phase of the crank pin on the flywheel (0: a positive '
        'offset raises the time ratio). Structural: set at start-up only.', True,
        -math.pi, math.pi),
    'coupling_offset': ParameterSpec(
        0.0, 'm', 'Commanded coupling offset (input shaft above the flywheel axis when > 0). '
        'The offset in force moves toward it at offset_rate_limit. |offset| <= '
        '0.9 * coupling_radius (the coupling locks at coupling_radius).', False),
    'offset_rate_limit': ParameterSpec(
        0.005, 'm/s', 'Speed at which the offset actuator moves the offset toward its '
        'command.', False, 1e-6, 1.0),
    'max_input_speed': ParameterSpec(
        60.0, 'rad/s', 'Largest |input speed| accepted from input_speed and '
        'input_speed_cmd.', False, 1e-3, 1e4),
    'input_speed': ParameterSpec(
        2.0 * math.pi, 'rad/s', 'Commanded input shaft speed (at start, on reset and when '
        'set; input_speed_cmd also commands it). Negative runs the shaper in reverse. '
        '|input_speed| <= max_input_speed.', False),
    'input_acceleration_limit': ParameterSpec(
        20.0, 'rad/s^2', 'Acceleration at which the input shaft speed ramps toward its '
        'command.', False, 1e-3, 1e5),
    'publish_rate': ParameterSpec(
        100.0, 'Hz', 'Rate of the timer that steps and publishes the mechanism (node clock). '
        'Set at start-up only.', True, 1.0, 1e4),
    'frame_id': ParameterSpec(
        'shaper_base', '', 'frame_id of the published joint_states and ram/twist headers. '
        'Non-empty.', False),
}
_DOUBLE = Parameter.Type.DOUBLE


def _shown(value):
    return f'{value:.6g}' if isinstance(value, float) else repr(value)


def _bounds(name, geometry):
    """Inclusive (low, high) for a double parameter, None where unbounded."""
    spec = PARAMETERS[name]
    if name == 'coupling_offset':
        return -geometry.max_safe_offset, geometry.max_safe_offset
    return spec.low, spec.high


def _allowed(name, values, geometry):
    """Readable statement of what a parameter accepts."""
    spec = PARAMETERS[name]
    unit = f' {spec.unit}' if spec.unit else ''
    if name == 'frame_id':
        return 'a non-empty string'
    if name == 'coupling_offset':
        return (f'[{_shown(-geometry.max_safe_offset)}, {_shown(geometry.max_safe_offset)}]'
                f' m (|offset| <= max_safe_offset = 0.9 x coupling_radius '
                f'{_shown(geometry.coupling_radius)} m)')
    if name == 'input_speed':
        limit = values['max_input_speed']
        return f'[{_shown(-limit)}, {_shown(limit)}] rad/s (|input_speed| <= max_input_speed)'
    if name in GEOMETRY_NAMES[:4]:
        text = f'a finite value > 0{unit}'
        return text + (' and < pivot_distance' if name == 'crank_radius' else '')
    low, high = _bounds(name, geometry)
    return f'[{_shown(low)}, {_shown(high)}]{unit}'


def refusal_reason(name, value, values, geometry, speed_command=None):
    """
    Why a parameter may not take a value, or None if it may.

    values holds every parameter as it would be after the change (for the cross-checks);
    geometry is the node's fixed geometry; speed_command is the input speed command in force
    (it may come from input_speed_cmd). Reasons name the parameter, the value and what is
    allowed, and are what `ros2 param set` prints.
    """
    spec = PARAMETERS[name]
    refused = f'{name} = {value!r} refused: '
    if spec.read_only:
        reason = (f'{refused}{name} is read-only (structural; set it at start-up, e.g. in '
                  f'config/shaper.yaml with --params-file); it stays {values[name]!r}'
                  f'{" " + spec.unit if spec.unit else ""}')
        if name in GEOMETRY_NAMES and isinstance(value, float):
            changed = dict(geometry.as_dict(), **{name: value})
            try:
                Geometry(**changed)
            except KinematicsError as error:
                reason += f'; the value would also break the geometry: {error}'
        return reason
    allowed = _allowed(name, values, geometry)
    if name == 'frame_id':
        if not isinstance(value, str) or not value.strip():
            return f'{refused}must be {allowed}'
        return None
    if not isinstance(value, float):
        return f'{refused}must be a floating-point number in {allowed}'
    if not math.isfinite(value):
        return f'{refused}not finite; allowed range {allowed}'
    if name == 'input_speed':
        if abs(value) > values['max_input_speed']:
            return f'{refused}outside the allowed range {allowed}'
        return None
    low, high = _bounds(name, geometry)
    if (low is not None and value < low) or (high is not None and value > high):
        return f'{refused}outside the allowed range {allowed}'
    if name == 'max_input_speed' and value < abs(values['input_speed']):
        return (f'{refused}below |input_speed| = {_shown(abs(values["input_speed"]))} rad/s; '
                f'lower input_speed first (allowed range {allowed})')
    if (name == 'max_input_speed' and speed_command is not None
            and value < abs(speed_command)):
        return (f'{refused}below the speed command in force '
                f'({_shown(speed_command)} rad/s, from input_speed_cmd); '
                f'command a lower speed first (allowed range {allowed})')
    return None


def _stamp(nanoseconds):
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


class _Samples:
    """Tick samples kept for the stroke-pair measurement (plain arrays, trimmed per pair)."""

    def __init__(self):
        self.clear()

    def clear(self):
        self.stamp_ns = []
        self.columns = {name: array('d') for name in (
            'ram_position', 'ram_velocity', 'offset', 'offset_rate', 'input_speed')}

    def append(self, stamp_ns, **values):
        self.stamp_ns.append(stamp_ns)
        for name, column in self.columns.items():
            column.append(values[name])
        if len(self.stamp_ns) > DIAGNOSTICS_BUFFER_LIMIT:
            self.keep_from(len(self.stamp_ns) - DIAGNOSTICS_BUFFER_LIMIT // 2)

    def keep_from(self, index):
        del self.stamp_ns[:index]
        for column in self.columns.values():
            del column[:index]

    def __len__(self):
        return len(self.stamp_ns)


class ShaperSimNode(Node):
    """Steps the mechanism on a timer and publishes it; see the module docstring."""

    def __init__(self, **node_options):
        super().__init__(SIM_NODE_NAME, **node_options)
        try:
            self._set_up()
        except Exception:
            self.destroy_node()  # a refused start-up leaves nothing on the graph
            raise

    def _set_up(self):
        self._values = {}
        for name in GEOMETRY_NAMES:
            self._declare(name, _PAPER)
        # Geometry errors name the field, the value and the limit (raised to main()).
        self._geometry = Geometry(**{name: self._values[name] for name in GEOMETRY_NAMES})
        for name in PARAMETERS:
            if name not in GEOMETRY_NAMES:
                self._declare(name, self._geometry)
        # input_speed before max_input_speed, so a too-fast start names input_speed.
        for name in sorted(PARAMETERS, key=lambda name: name != 'input_speed'):
            reason = refusal_reason(name, self._values[name], self._values, self._geometry)
            if reason and not PARAMETERS[name].read_only:
                raise ValueError(f'start-up value refused: {reason}')
        self._stepper = ShaperStepper(
            self._geometry, self._values['input_speed'], self._values['coupling_offset'],
            self._values['input_acceleration_limit'], self._values['offset_rate_limit'])
        self._paused = False
        self._samples = _Samples()
        self._theory_cache = {}
        self._last_velocity_positive = None

        self._joint_state = JointState(name=list(JOINT_NAMES))
        self._twist = TwistStamped()
        self._joint_state_publisher = self.create_publisher(JointState, JOINT_STATES_TOPIC, 10)
        self._twist_publisher = self.create_publisher(TwistStamped, RAM_TWIST_TOPIC, 10)
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        self.create_subscription(Float64, SPEED_COMMAND_TOPIC, self._on_speed_command, 10)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._timer = self.create_timer(1.0 / self._values['publish_rate'], self._on_timer)
        self.get_logger().info(
            f'running: offset {self._values["coupling_offset"]} m, input speed '
            f'{self._values["input_speed"]} rad/s, {self._values["publish_rate"]} Hz')

    def _declare(self, name, geometry):
        spec = PARAMETERS[name]
        unit = f' [{spec.unit}]' if spec.unit else ''
        values = dict(_default_values(), **self._values)
        descriptor = ParameterDescriptor(
            name=name, description=f'{spec.description}{unit}', read_only=spec.read_only,
            additional_constraints=f'allowed: {_allowed(name, values, geometry)}')
        if isinstance(spec.default, float):
            low, high = _bounds(name, geometry)
            if low is not None:
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=low, to_value=high, step=0.0)]
        try:
            self._values[name] = self.declare_parameter(name, spec.default, descriptor).value
        except (InvalidParameterTypeException, InvalidParameterValueException) as error:
            # rclpy's own wording names no allowed range; give this node's reason instead.
            given = self._parameter_overrides.get(name)
            reason = given is not None and refusal_reason(name, given.value, values, geometry)
            wrong_type = isinstance(error, InvalidParameterTypeException)
            if wrong_type and isinstance(spec.default, float):
                reason = (f'{name} = {given.value!r} refused: must be a double, written with a '
                          f'decimal point (e.g. {spec.default!r}); allowed: '
                          f'{_allowed(name, values, geometry)}')
            raise ValueError(reason or f'{name}: {error}; allowed: '
                             f'{_allowed(name, values, geometry)}') from None

    # Parameters ---------------------------------------------------------------------------

    def _coerced(self, parameter):
        """Take an integer for a double parameter as that double (`... offset 0`)."""
        spec = PARAMETERS.get(parameter.name)
        if (spec is not None and isinstance(spec.default, float)
                and parameter.type_ == Parameter.Type.INTEGER):
            return Parameter(parameter.name, _DOUBLE, float(parameter.value))
        return parameter

    def _refusal(self, parameters):
        candidate = dict(self._values)
        # Read-only values never change, so the candidate keeps them (reasons show them).
        candidate.update((p.name, p.value) for p in parameters
                         if p.name in PARAMETERS and not PARAMETERS[p.name].read_only)
        for parameter in parameters:
            if parameter.name in PARAMETERS:
                reason = refusal_reason(parameter.name, parameter.value, candidate,
                                        self._geometry, self._stepper.speed_command)
                if reason:
                    return reason
        return None

    def set_parameters_atomically(self, parameter_list):
        """Check our parameters first, so every refusal gets this node's full reason."""
        parameter_list = [self._coerced(p) for p in parameter_list]
        unknown = [p.name for p in parameter_list if not self.has_parameter(p.name)]
        # rclpy's own refusal of an undeclared name names none ("parameter(s): []").
        reason = unknown and (
            f'{", ".join(unknown)}: no such parameter of {self.get_name()}; its parameters: '
            f'{", ".join(sorted(PARAMETERS))}')
        reason = reason or self._refusal(parameter_list)
        if reason:
            self.get_logger().warning(reason)
            return SetParametersResult(successful=False, reason=reason)
        return super().set_parameters_atomically(parameter_list)

    def set_parameters(self, parameter_list):
        return [self.set_parameters_atomically([p]) for p in parameter_list]

    def _check_parameters(self, parameters):
        reason = self._refusal(parameters)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, parameters):
        for parameter in parameters:
            if parameter.name not in PARAMETERS:
                continue
            value = self._values[parameter.name] = parameter.value
            if parameter.name == 'coupling_offset':
                self._stepper.set_offset_command(value)
            elif parameter.name == 'input_speed':
                self._stepper.set_speed_command(value)
            elif parameter.name == 'input_acceleration_limit':
                self._stepper.set_limits(input_acceleration_limit=value)
            elif parameter.name == 'offset_rate_limit':
                self._stepper.set_limits(offset_rate_limit=value)
            self.get_logger().info(f'{parameter.name} set to {value!r}')

    # Commands and services ----------------------------------------------------------------

    def _on_speed_command(self, message):
        value = message.data
        limit = self._values['max_input_speed']
        if not math.isfinite(value) or abs(value) > limit:
            self.get_logger().warning(
                f'input_speed_cmd {value!r} rad/s ignored: allowed finite values in '
                f'[{_shown(-limit)}, {_shown(limit)}] rad/s (max_input_speed)',
                throttle_duration_sec=_WARNING_PERIOD)
            return
        self._stepper.set_speed_command(value)

    def _on_reset(self, request, response):
        del request
        speed, offset = self._values['input_speed'], self._values['coupling_offset']
        self._stepper.reset(speed, offset)
        self._forget_samples()
        response.success = True
        response.message = (f'reset: input angle 0 rad, input speed {speed!r} rad/s, '
                            f'offset {offset!r} m')
        self.get_logger().info(response.message)
        return response

    def _on_pause(self, request, response):
        if request.data != self._paused:
            self._paused = request.data
            # No motion during the pause; the next sample continues from the held state.
            self._stepper.resync()
            self._forget_samples()
        response.success = True
        response.message = 'paused' if self._paused else 'running'
        self.get_logger().info(response.message)
        return response

    @property
    def paused(self):
        return self._paused

    @property
    def stepper(self):
        return self._stepper

    @property
    def geometry(self):
        return self._geometry

    # Stepping and publishing --------------------------------------------------------------

    def _on_timer(self):
        if self._paused:
            return
        stamp_ns = self.get_clock().now().nanoseconds
        if stamp_ns == 0:
            self.get_logger().info('use_sim_time is true and no /clock has arrived yet: '
                                   'waiting for it', throttle_duration_sec=_WARNING_PERIOD)
        self.publish_at(stamp_ns)

    def publish_at(self, stamp_ns):
        """
        Step to stamp_ns (node-clock nanoseconds) and publish that sample.

        Returns False when nothing was published: a zero stamp (simulated time not started),
        a repeated stamp, or a non-finite state (never published).
        """
        stepper = self._stepper
        if stamp_ns <= 0 or stamp_ns == stepper.stamp_ns:
            return False
        resets = stepper.time_resets
        sample = stepper.advance_to(stamp_ns)
        if stepper.time_resets != resets:
            self.get_logger().warning(
                'node clock went back (simulated time restarted?): holding the state and '
                'continuing from the new time', throttle_duration_sec=_WARNING_PERIOD)
            self._forget_samples()
        positions = array('d', (stepper.input_angle, wrap_angle(sample.flywheel_angle),
                                sample.lever_angle, sample.ram_position, stepper.offset))
        velocities = array('d', (stepper.input_speed, sample.flywheel_speed,
                                 sample.lever_speed, sample.ram_velocity, stepper.offset_rate))
        if not all(map(math.isfinite, positions + velocities)):
            self.get_logger().error(
                f'non-finite state at {stamp_ns} ns not published: positions {positions}, '
                f'velocities {velocities}', throttle_duration_sec=_WARNING_PERIOD)
            return False
        stamp = _stamp(stamp_ns)
        frame_id = self._values['frame_id']
        joint_state = self._joint_state
        joint_state.header.stamp = stamp
        joint_state.header.frame_id = frame_id
        joint_state.position = positions
        joint_state.velocity = velocities
        self._joint_state_publisher.publish(joint_state)
        twist = self._twist
        twist.header.stamp = stamp
        twist.header.frame_id = frame_id
        twist.twist.linear.x = sample.ram_velocity
        self._twist_publisher.publish(twist)
        self._record(stamp_ns, sample)
        return True

    # Diagnostics --------------------------------------------------------------------------

    def _forget_samples(self):
        self._samples.clear()
        self._last_velocity_positive = None

    def _record(self, stamp_ns, sample):
        stepper = self._stepper
        self._samples.append(stamp_ns, ram_position=sample.ram_position,
                             ram_velocity=sample.ram_velocity, offset=stepper.offset,
                             offset_rate=stepper.offset_rate, input_speed=stepper.input_speed)
        positive = sample.ram_velocity >= 0.0
        # A cutting stroke beginning ends the pair before it: measure only then.
        if self._last_velocity_positive and not positive:
            self._measure_pairs(stamp_ns)
        self._last_velocity_positive = positive

    def _measure_pairs(self, stamp_ns):
        samples = self._samples
        origin = samples.stamp_ns[0]
        time = [(ns - origin) / 1e9 for ns in samples.stamp_ns]
        columns = samples.columns
        pairs = find_stroke_pairs(time, columns['ram_position'], columns['ram_velocity'])
        for index in range(len(pairs.cutting_time)):
            self._publish_pair(stamp_ns, origin, pairs, index)
        # Keep the two samples around the reversal just found: the next pair starts there.
        samples.keep_from(len(samples) - 2)

    def _theory(self, offset, speed):
        """Core values for a steady offset and speed (cached per unit |speed|)."""
        key = (offset, speed > 0.0)
        if key not in self._theory_cache:
            if len(self._theory_cache) > 64:
                self._theory_cache.clear()
            self._theory_cache[key] = steady_theory(self._geometry, offset,
                                                    math.copysign(1.0, speed))
        unit = self._theory_cache[key]
        scale = abs(speed)
        return {
            'time_ratio_theory': unit.time_ratio,
            'speed_ratio_theory': unit.speed_ratio,
            'peak_speed_ratio_theory': unit.peak_speed_ratio,
            'cutting_time_theory': unit.cutting_time / scale,
            'return_time_theory': unit.return_time / scale,
            'peak_cutting_speed_theory': unit.peak_cutting_speed * scale,
            'peak_return_speed_theory': unit.peak_return_speed * scale,
        }

    def _publish_pair(self, stamp_ns, origin, pairs, index):
        columns = self._samples.columns
        first, last = int(pairs.first_sample[index]), int(pairs.last_sample[index])
        offsets = columns['offset'][first:last + 1]
        speeds = columns['input_speed'][first:last + 1]
        offset, speed = offsets[-1], speeds[-1]
        offset_steady = (min(offsets) == max(offsets)
                         and not any(columns['offset_rate'][first:last]))
        speed_steady = min(speeds) == max(speeds)
        measured = {name: float(getattr(pairs, name)[index]) for name in (
            'cutting_time', 'return_time', 'time_ratio', 'peak_cutting_speed',
            'peak_return_speed', 'mid_cutting_speed', 'mid_return_speed', 'speed_ratio',
            'peak_speed_ratio')}
        values = dict(measured)
        values['pair_start'] = origin / 1e9 + float(pairs.cutting_start[index])
        values['pair_end'] = origin / 1e9 + float(pairs.return_end[index])
        values['coupling_offset'] = offset
        values['input_speed'] = speed
        if speed != 0.0:
            values.update(self._theory(offset, speed))
        key_values = [KeyValue(key=key, value=repr(value)) for key, value in values.items()
                      if math.isfinite(value)]
        key_values.append(KeyValue(key='offset_steady', value=str(offset_steady).lower()))
        key_values.append(KeyValue(key='input_speed_steady', value=str(speed_steady).lower()))
        steady = 'steady' if offset_steady and speed_steady else 'NOT steady (ratios mixed)'
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK, name=STROKE_PAIR_STATUS, hardware_id=SIM_NODE_NAME,
            message=(f'TR {measured["time_ratio"]:.4f}, SR {measured["speed_ratio"]:.4f} '
                     f'(peak {measured["peak_speed_ratio"]:.4f}) at offset {offset:.6g} m, '
                     f'{speed:.6g} rad/s, {steady}'),
            values=key_values)
        message = DiagnosticArray(status=[status])
        message.header.stamp = _stamp(stamp_ns)
        self._diagnostics_publisher.publish(message)


def _default_values():
    return {name: spec.default for name, spec in PARAMETERS.items()}


def main(args=None):
    """Run the node until Ctrl-C or SIGTERM; exit 2 on bad start-up arguments or parameters."""
    try:
        init_rclpy(args)
    except RCLError as error:  # a malformed -p or params file, said by rcl
        print(f'{SIM_NODE_NAME}: cannot start: {rcl_error_text(error)}', file=sys.stderr)
        return 2
    node = None
    try:
        with StopRequest() as stop:
            try:
                node = ShaperSimNode()
            except ValueError as error:
                # Say which start-up value and why, no traceback (KinematicsError included).
                print(f'{SIM_NODE_NAME}: cannot start: {error}', file=sys.stderr)
                return 2
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            spin_until_stopped(executor, stop)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
