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

A thin adapter: ShaperStepper (qrm_ros.core.stepping) integrates the input angle and moves the
offset; the kinematics core gives every other state in closed form; StrokeMonitor
(qrm_ros.core.stroke_monitor) measures each completed stroke pair for /diagnostics, a step at a
time after the ticks so that no tick waits for it; the parameters, their rules and effects
are data (qrm_ros.node.shaper_parameters). This module only turns parameters into descriptors,
commands into stepper calls and states into messages.
"""

from array import array
from collections import deque
import difflib
import math
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped
from qrm_ros.core.cutting_speed_hold import CUTTING_SPEED_FIGURES, hold_offset
from qrm_ros.core.dynamics import (efforts, Loads, MassProperties, MotorDrive, parameter_names,
                                   ram_load_force)
from qrm_ros.core.effort_theory import BackgroundTheory, Setting, THEORY_FIGURES
from qrm_ros.core.motor_stepper import MotorStepper
from qrm_ros.core.geometry import Geometry
from qrm_ros.node.linkage_markers import (delete_all_marker_array, linkage_marker_array,
                                          stamp_message)
from qrm_ros.core.names import (CUTTING_SPEED_STATUS, DIAGNOSTICS_TOPIC, DRIVE_STATUS, JOINT_NAMES,
                                JOINT_STATES_TOPIC, LINKAGE_MARKERS_TOPIC, RAM_TWIST_TOPIC,
                                SIM_NODE_NAME, SPEED_COMMAND_TOPIC, STROKE_PAIR_STATUS)
from qrm_ros.node.ros_process import (executor_kind, init_rclpy, new_executor, RCLError,
                                      rcl_error_text, spin_until_stopped, StopRequest)
from qrm_ros.node.shaper_parameters import (allowed_text, default_values, GEOMETRY_NAMES,
                                            MARKER_SLICING_RATE, PARAMETERS, refusal_reason, shown,
                                            View)
from qrm_ros.core.stepping import ShaperStepper, wrap_angle
from qrm_ros.core.units import NANOSECONDS_PER_SECOND
from qrm_ros.core.stroke_monitor import StrokeMonitor
from qrm_ros.core.strokes import run_steps
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_parameters
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

__all__ = ['JOINT_NAMES', 'PARAMETERS', 'ShaperSimNode', 'main', 'refusal_reason']

_WARNING_PERIOD = 1.0  # s, throttle for repeated warnings
# s: the longest another thread of the node (the motor kernel's loader, the theory's reply
# reader) may hold the GIL while a tick waits for it (Python's default is 5 ms).
GIL_SWITCH_INTERVAL = 1e-4
# Stroke-pair steps run after a tick while less than this fraction of the timer's period has
# gone since the tick began: the rest absorbs the host's noise.
PAIR_STEP_SHARE = 0.5
# s: the whole marker array is sent at least this often (a viewer started later sees the
# still parts within it), the moving markers alone in between.
MARKER_REFRESH_PERIOD = 1.0
_STALL_REPEAT_NS = 1_000_000_000  # a stall's ERROR status is repeated this often
# Publisher history, in seconds of messages at the publish rate: a reliable subscriber that
# keeps up on average (the recorder) but stalls for a moment (a loaded machine) is resent
# what it missed instead of losing it, as KEEP_LAST 10 (0.01 s at 1 kHz) did.
PUBLISHER_HISTORY_SECONDS = 1.0
MIN_PUBLISHER_DEPTH = 10
# Request queue of the node's own services: a burst of calls is answered, not dropped
# (the default service QoS keeps 10; rclpy's parameter services keep 1000, as here).
SERVICE_QOS = qos_profile_parameters
_PAPER = Geometry.paper()
# Overrides rclpy declares itself; not this node's to report as unknown.
_RCLPY_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def _coerce_integers_to_doubles(parameters):
    """Take an integer for a double parameter as that double (`ros2 param set ... 0`)."""
    return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            if (p.type_ == Parameter.Type.INTEGER and p.name in PARAMETERS
                and isinstance(PARAMETERS[p.name].default, float)) else p
            for p in parameters]


class ShaperSimNode(Node):
    """Steps the mechanism on a timer and publishes it; see the module docstring."""

    def __init__(self, **node_options):
        super().__init__(SIM_NODE_NAME, **node_options)
        self._theory = BackgroundTheory()
        # Completed stroke pairs, measured and reported a step at a time after the ticks
        # (_run_pair_steps): a pair of thousands of samples takes about a millisecond, which
        # no tick may wait for. Not on a thread: there a pair held a 4 kHz node's ticks
        # back for its whole length (the GIL), whatever the switch interval.
        self._pair_jobs = deque()
        self._pair_lock = threading.Lock()  # one caller steps the jobs at a time
        self._pair_step_budget_ns = 0
        self._pair_steps_waited = False  # the last tick ran no step: the next runs one
        self._pair_reports_published = 0
        if sys.getswitchinterval() > GIL_SWITCH_INTERVAL:
            sys.setswitchinterval(GIL_SWITCH_INTERVAL)
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
        view = self._view(self._values)
        for name in sorted(PARAMETERS, key=lambda name: name != 'input_speed'):
            reason = refusal_reason(name, self._values[name], view, starting=True)
            if reason:
                raise ValueError(f'start-up value refused: {reason}')
        self._report_unknown_overrides()
        self._stepper = None  # made below, from the dynamics in force
        self.update_dynamics()
        self._stepper = self._new_stepper(self._values['drive'])
        self._stall_reason = None
        self._stall_reported_ns = 0
        self._hold = None
        self._paused = False
        self._monitor = StrokeMonitor(self._geometry)
        # What the effort theory of a pair depends on, and since when (ns) it has held.
        self._setting = None
        self._setting_since_ns = 0

        depth = max(MIN_PUBLISHER_DEPTH,
                    math.ceil(PUBLISHER_HISTORY_SECONDS * self._values['publish_rate']))
        self._joint_state = JointState(name=list(JOINT_NAMES))
        self._twist = TwistStamped()
        self._joint_state_publisher = self.create_publisher(JointState, JOINT_STATES_TOPIC,
                                                            depth)
        self._twist_publisher = self.create_publisher(TwistStamped, RAM_TWIST_TOPIC, depth)
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, MIN_PUBLISHER_DEPTH)
        self._marker_publisher = self.create_publisher(MarkerArray, LINKAGE_MARKERS_TOPIC,
                                                       MIN_PUBLISHER_DEPTH)
        self._marker_period_ns = 0
        self._next_markers_ns = 0
        # A frame's markers still to publish, one a tick (above MARKER_SLICING_RATE).
        self._marker_slices = []
        self._slice_markers = self._values['publish_rate'] > MARKER_SLICING_RATE
        self._published_stamp_ns = None  # the markers draw the latest published sample
        self._clear_markers = False
        # What the still markers last sent show (offset, reversed, frame, loads), and when (s).
        self._still_markers = None
        self._still_markers_sent = 0.0
        self.set_marker_rate(self._values['marker_rate'])
        self.create_subscription(Float64, SPEED_COMMAND_TOPIC, self._on_speed_command, 10)
        self.create_service(Trigger, '~/reset', self._on_reset, qos_profile=SERVICE_QOS)
        self.create_service(SetBool, '~/pause', self._on_pause, qos_profile=SERVICE_QOS)
        self._guard_parameter_services()
        self.add_pre_set_parameters_callback(_coerce_integers_to_doubles)
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._timer = self.create_timer(1.0 / self._values['publish_rate'], self._on_timer)
        self._pair_step_budget_ns = round(PAIR_STEP_SHARE * NANOSECONDS_PER_SECOND
                                          / self._values['publish_rate'])
        if self._values['cutting_speed_target']:
            self.command_offset()
        self.get_logger().info(
            f'running: offset {self._values["coupling_offset"]} m, input speed '
            f'{self._values["input_speed"]} rad/s, {self._values["publish_rate"]} Hz')

    def _view(self, values, speed_command=None):
        if speed_command is None:
            speed_command = values['input_speed']
        return View(values, self._geometry, speed_command)

    def _declare(self, name, geometry):
        spec = PARAMETERS[name]
        unit = f' [{spec.unit}]' if spec.unit else ''
        view = View(dict(default_values(), **self._values), geometry, 0.0)
        descriptor = ParameterDescriptor(
            name=name, description=f'{spec.description}{unit}', read_only=spec.read_only,
            additional_constraints=f'allowed: {allowed_text(name, view)}')
        bounds = spec.rule.descriptor_bounds(geometry)
        if bounds is not None:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=bounds[0], to_value=bounds[1], step=0.0)]
        try:
            self._values[name] = self.declare_parameter(name, spec.default, descriptor).value
        except (InvalidParameterTypeException, InvalidParameterValueException) as error:
            # rclpy's own wording names no allowed range; give this node's reason instead.
            given = self._start_up_overrides().get(name)
            value = given.value if given is not None else None
            if isinstance(error, InvalidParameterTypeException) and isinstance(spec.default,
                                                                               float):
                reason = (f'{name} = {value!r} refused: must be a double, written with a '
                          f'decimal point (e.g. {spec.default!r}); allowed: '
                          f'{allowed_text(name, view)}')
            else:
                reason = refusal_reason(name, value, view, starting=True)
            raise ValueError(reason or f'{name}: {error}; allowed: '
                             f'{allowed_text(name, view)}') from None

    # rclpy internals, in one place ---------------------------------------------------------
    # Three things rclpy does not offer publicly: the start-up overrides (to name a refused
    # value and to report unknown names), a check before rclpy's descriptor checks (whose
    # wording names no allowed range), and the parameter services' request decoding (which
    # raises out of the executor on a malformed ParameterValue type and would stop the node).
    # test_shaper_sim.py exercises each, so an rclpy update that breaks them fails a test.

    def _start_up_overrides(self):
        """Parameter values given at start-up (--params-file, -p, parameter_overrides)."""
        return self._parameter_overrides

    def _report_unknown_overrides(self):
        unknown = sorted(set(self._start_up_overrides()) - set(PARAMETERS)
                         - set(_RCLPY_PARAMETERS))
        for name in unknown:
            close = difflib.get_close_matches(name, PARAMETERS, n=1)
            hint = f' (did you mean {close[0]}?)' if close else ''
            self.get_logger().warning(
                f'start-up parameter {name} ignored: no such parameter of {self.get_name()}'
                f'{hint}; its parameters: {", ".join(sorted(PARAMETERS))}')

    def _guard_parameter_services(self):
        """Answer malformed set requests with a reason instead of raising (see above)."""
        guarded = {SetParameters: self._on_set_parameters_request,
                   SetParametersAtomically: self._on_set_parameters_atomically_request}
        for service in self.services:  # rclpy's parameter services: one of each type
            if service.srv_type in guarded:
                service.callback = guarded[service.srv_type]

    def _decoded(self, messages):
        """(parameters, None), or (None, a refusal) when a message cannot be decoded."""
        parameters = []
        for message in messages:
            try:
                parameters.append(Parameter.from_parameter_msg(message))
            except (ValueError, TypeError) as error:
                reason = (f'{message.name}: malformed request refused: {error} (ParameterValue'
                          f'.type must be one of {[t.value for t in Parameter.Type]})')
                self.get_logger().warning(reason, throttle_duration_sec=_WARNING_PERIOD)
                return None, SetParametersResult(successful=False, reason=reason)
        return parameters, None

    def _on_set_parameters_request(self, request, response):
        for message in request.parameters:
            parameters, refusal = self._decoded([message])
            response.results.append(refusal or self.set_parameters_atomically(parameters))
        return response

    def _on_set_parameters_atomically_request(self, request, response):
        parameters, refusal = self._decoded(request.parameters)
        response.result = refusal or self.set_parameters_atomically(parameters)
        return response

    def set_parameters_atomically(self, parameter_list):
        """Check our parameters first, so every refusal gets this node's full reason."""
        parameter_list = _coerce_integers_to_doubles(parameter_list)
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

    # Parameters ---------------------------------------------------------------------------

    def _refusal(self, parameters):
        """Return the first refusal of a change, judged as a whole (all values after it)."""
        changed = {p.name: p.value for p in parameters if p.name in PARAMETERS}
        candidate = dict(self._values)
        # Read-only values never change, so the candidate keeps them (reasons show them).
        candidate.update((name, value) for name, value in changed.items()
                         if not PARAMETERS[name].read_only)
        # A change that sets input_speed also sets the speed command in force.
        command = None if 'input_speed' in changed else self._stepper.speed_command
        view = self._view(candidate, command)
        for name, value in changed.items():
            reason = refusal_reason(name, value, view)
            if reason:
                return reason
        return None

    def _check_parameters(self, parameters):
        reason = self._refusal(parameters)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, parameters):
        for parameter in parameters:
            spec = PARAMETERS.get(parameter.name)
            if spec is None:
                continue
            value = self._values[parameter.name] = parameter.value
            if spec.apply is not None:
                spec.apply(self, value)
            self.get_logger().info(f'{parameter.name} set to {value!r}')

    # Commands and services ----------------------------------------------------------------

    def _on_speed_command(self, message):
        value = message.data
        limit = self._values['max_input_speed']
        if not math.isfinite(value) or abs(value) > limit:
            self.get_logger().warning(
                f'input_speed_cmd {value!r} rad/s ignored: allowed finite values in '
                f'[{shown(-limit)}, {shown(limit)}] rad/s (max_input_speed)',
                throttle_duration_sec=_WARNING_PERIOD)
            return
        self.command_speed(value)

    def command_speed(self, input_speed):
        """Command the input speed; a held cutting speed follows it through the offset."""
        self._stepper.set_speed_command(input_speed)
        if self._values['cutting_speed_target']:
            self.command_offset()

    def command_offset(self):
        """
        Command the offset: coupling_offset by hand, or the cutting speed's.

        While cutting_speed_target is set, the offset that gives it at the speed command in
        force (the nearest reachable one, with a WARN, when a speed change has put the
        target out of reach).
        """
        values = self._values
        target = values['cutting_speed_target']
        if not target:
            self._hold = None
            self._stepper.set_offset_command(values['coupling_offset'])
            return
        answer = hold_offset(self._geometry, self._stepper.speed_command, target,
                             values['cutting_speed_definition'])
        self._stepper.set_offset_command(answer.offset)
        if answer.problem and (self._hold is None or self._hold.problem != answer.problem):
            self.get_logger().warning(answer.problem)
        self._hold = answer
        self._publish_hold_status()

    def _on_reset(self, request, response):
        del request
        speed, offset = self._values['input_speed'], self._values['coupling_offset']
        self._stepper.reset(speed, offset)
        if self._values['cutting_speed_target']:
            self.command_offset()  # from the reset state, toward the held cutting speed
        self._monitor.clear()
        self._clear_markers = True  # DELETEALL before the next markers
        self._marker_slices = []  # the rest of a frame from before: the DELETEALL clears it
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
            self._monitor.clear()
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
        if self._paused:  # the held state, still drawn for a viewer that starts now
            self._publish_markers_if_due(self.get_clock().now().nanoseconds)
            self._run_pair_steps(time.monotonic_ns())
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
        started_ns = time.monotonic_ns()
        stepper = self._stepper
        if stamp_ns <= 0 or stamp_ns == stepper.stamp_ns:
            return False
        resets = stepper.time_resets
        sample = stepper.advance_to(stamp_ns)
        if stepper.time_resets != resets:
            self.get_logger().warning(
                'node clock went back (simulated time restarted?): holding the state and '
                'continuing from the new time', throttle_duration_sec=_WARNING_PERIOD)
            self._monitor.clear()
        positions = array('d', (stepper.input_angle, wrap_angle(sample.flywheel_angle),
                                sample.lever_angle, sample.ram_position, stepper.offset))
        velocities = array('d', (stepper.input_speed, sample.flywheel_speed,
                                 sample.lever_speed, sample.ram_velocity, stepper.offset_rate))
        # What drives each joint (N m, N), exact at the stamp. The speed drive supplies the
        # input torque the prescribed motion needs against inertia, gravity and the loads;
        # the motor stepper integrates the motion from the motor's torque and knows them.
        if isinstance(stepper, MotorStepper):
            joint_efforts = array('d', stepper.efforts())
            self._report_stall(stepper, stamp_ns)
        else:
            ram_force = ram_load_force(self._loads, sample.ram_position, sample.ram_velocity,
                                       self._geometry.ram_stroke)
            joint_efforts = array('d', efforts(
                self._geometry, self._mass, stepper.offset, stepper.input_angle,
                stepper.input_speed, stepper.input_acceleration, stepper.offset_rate, 0.0,
                ram_force))
        if not all(map(math.isfinite, positions + velocities + joint_efforts)):
            self.get_logger().error(
                f'non-finite state at {stamp_ns} ns not published: positions {positions}, '
                f'velocities {velocities}, efforts {joint_efforts}',
                throttle_duration_sec=_WARNING_PERIOD)
            return False
        # The messages are built once; each tick only fills in its values.
        seconds, nanoseconds = divmod(stamp_ns, NANOSECONDS_PER_SECOND)
        frame_id = self._values['frame_id']
        joint_state = self._joint_state
        joint_state.header.stamp.sec = seconds
        joint_state.header.stamp.nanosec = nanoseconds
        joint_state.header.frame_id = frame_id
        joint_state.position = positions
        joint_state.velocity = velocities
        joint_state.effort = joint_efforts
        self._joint_state_publisher.publish(joint_state)
        twist = self._twist
        twist.header.stamp.sec = seconds
        twist.header.stamp.nanosec = nanoseconds
        twist.header.frame_id = frame_id
        twist.twist.linear.x = sample.ram_velocity
        self._twist_publisher.publish(twist)
        self._published_stamp_ns = stamp_ns
        # The speed drive's sample is the core's state: the markers need not recompute it.
        self._publish_markers_if_due(stamp_ns, None if isinstance(stepper, MotorStepper)
                                     else sample)
        self._note_setting(stepper, stamp_ns)
        completed = self._monitor.collect(stamp_ns, sample.ram_position, sample.ram_velocity,
                                          stepper.offset, stepper.offset_rate,
                                          stepper.input_speed, joint_efforts[0],
                                          joint_efforts[-1])
        if completed is not None:
            # What the report depends on is taken now, as it stands at the pair's end.
            self._pair_jobs.append(self._report_pairs(
                completed, self._setting, self._setting_since_ns,
                self._values['cutting_speed_target'], self._values['cutting_speed_definition']))
        self._run_pair_steps(started_ns)
        return True

    def _run_pair_steps(self, started_ns):
        """
        Run stroke-pair steps, oldest pair first, while there is budget left.

        The budget is PAIR_STEP_SHARE of the timer's period since started_ns (the tick's
        start). A tick that used it up itself runs none, unless the tick before ran none
        either: the pairs always progress. Skipped while wait_for_pair_reports steps them.
        """
        jobs = self._pair_jobs
        if not jobs or not self._pair_lock.acquire(blocking=False):
            return
        try:
            budget_ns = self._pair_step_budget_ns
            ran = False
            while jobs:
                if (time.monotonic_ns() - started_ns >= budget_ns
                        and (ran or not self._pair_steps_waited)):
                    self._pair_steps_waited = not ran
                    return
                try:
                    next(jobs[0])
                except StopIteration:
                    jobs.popleft()
                ran = True
            self._pair_steps_waited = False
        finally:
            self._pair_lock.release()

    def wait_for_pair_reports(self, timeout=None):
        """Report every pair completed so far, now, in this thread (for tests and tools)."""
        if not self._pair_lock.acquire(timeout=-1 if timeout is None else timeout):
            raise TimeoutError('the stroke pairs are being reported by another caller')
        try:
            while self._pair_jobs:
                run_steps(self._pair_jobs.popleft())
        finally:
            self._pair_lock.release()

    @property
    def pair_reports_published(self):
        """How many stroke-pair statuses this node has published on /diagnostics."""
        return self._pair_reports_published

    def _report_pairs(self, completed, setting, setting_since_ns, target, definition):
        """Measure and publish completed stroke pairs, a step per next() (_run_pair_steps)."""
        try:
            for report in (yield from self._monitor.measure_steps(completed)):
                yield
                message = self._pair_message(report, setting, setting_since_ns, target,
                                             definition)
                yield
                self._diagnostics_publisher.publish(message)
                self._pair_reports_published += 1
        except Exception as error:  # noqa: B902 said; the ticks and later pairs go on
            self.get_logger().error(f'stroke pair at {completed.stamp_ns} ns not reported: '
                                    f'{type(error).__name__}: {error}')

    def _note_setting(self, stepper, stamp_ns):
        # The parameter sets compare by identity: any change of them makes new ones.
        setting = (stepper, self._mass, self._loads, self._motor, stepper.offset,
                   self._setting_speed(stepper))
        if setting != self._setting:
            self._setting, self._setting_since_ns = setting, stamp_ns

    @staticmethod
    def _setting_speed(stepper):
        """Return the speed a steady pair runs at: the drive's, or the motor's reference."""
        if isinstance(stepper, MotorStepper):
            return stepper.speed_reference
        return stepper.input_speed

    def _effort_theory(self, report, setting, setting_since_ns):
        """Return the pair's effort theory as key-values, and a word on where it stands."""
        if report.pair_start * NANOSECONDS_PER_SECOND < setting_since_ns:
            return [], 'none: the setting changed during the pair'
        stepper, mass, loads, motor, offset, speed = setting
        theory, problem = self._theory.lookup(Setting(
            self._geometry, mass, loads, motor if isinstance(stepper, MotorStepper) else None,
            offset, speed))
        if problem:
            return [], f'unavailable: {problem}'
        if theory is None:
            return [], 'pending: worked out in the background'
        values = [KeyValue(key=f'{name}_theory', value=repr(theory[name]))
                  for name in THEORY_FIGURES if theory[name] is not None]
        return values, ('steady setting' if values else
                        'none: no steady running at this setting (stopped or stalled)')

    def destroy_node(self):
        self.wait_for_pair_reports()  # they go out before the publisher does
        self._theory.close()
        return super().destroy_node()

    def update_dynamics(self):
        """Take the mass, load and motor parameters in force (checked by their rules)."""
        values = self._values
        self._mass, self._loads, self._motor = (
            kind(**{field: values[name]
                    for field, name in zip(kind.field_names(), parameter_names(kind))})
            for kind in (MassProperties, Loads, MotorDrive))
        if isinstance(self._stepper, MotorStepper):
            self._stepper.set_dynamics(self._mass, self._loads, self._motor)

    def _new_stepper(self, drive):
        values = self._values
        arguments = (values['input_speed'], values['coupling_offset'],
                     values['input_acceleration_limit'], values['offset_rate_limit'])
        if drive == 'motor':
            return MotorStepper(self._geometry, self._mass, self._loads, self._motor, *arguments)
        return ShaperStepper(self._geometry, *arguments)

    def set_drive(self, drive):
        """Switch between the ideal speed source and the motor, keeping the state."""
        old = self._stepper
        new = self._new_stepper(drive)
        if old.stamp_ns is not None:
            new.restore(old.stamp_ns, old.input_angle, old.input_speed, old.offset)
        new.set_speed_command(old.speed_command)
        new.set_offset_command(old.offset_command)
        self._stepper = new
        self._monitor.clear()  # a pair spanning the switch would mix two drives

    # Markers -------------------------------------------------------------------------------

    def set_marker_rate(self, rate):
        """
        Publish the linkage markers at rate Hz (0: stop), each right after a tick.

        Not on a timer of their own: one firing just before a tick was due made the tick
        late by the markers' conversion (up to 0.75 ms in a running node); right after a
        tick they use the time to the next one. Each frame is built within one tick period of
        when it is due (so at most once per tick); above MARKER_SLICING_RATE its markers then
        go out one a tick, and the next frame waits for them (at 4 kHz, a moving frame's four
        markers take 1.25 ms of a 33 ms period at 30 Hz).
        """
        self._marker_period_ns = round(NANOSECONDS_PER_SECOND / rate) if rate > 0.0 else 0
        self._next_markers_ns = 0

    def _publish_markers_if_due(self, stamp_ns, sample=None):
        if self._marker_slices:  # a frame under way: its next marker, the next frame waits
            self._marker_publisher.publish(self._marker_slices.pop())
            return
        period, due = self._marker_period_ns, self._next_markers_ns
        if period and (stamp_ns >= due or stamp_ns < due - period):  # due, or time went back
            # The next a period after this one's due time (the rate kept on average), or
            # after now when the first, a period behind or after the clock went back.
            late = stamp_ns - due
            self._next_markers_ns = (due if 0 <= late < period else stamp_ns) + period
            if self._slice_markers:  # built now, sent from the next tick on
                frame = self._marker_frame(sample)
                self._marker_slices = [
                    MarkerArray(markers=[marker]) for markers in reversed(frame or ())
                    for marker in reversed(markers.markers)]
            else:
                self._publish_frame(sample)

    def publish_markers(self):
        """
        Publish the mechanism as markers at the latest published sample (its stamp), now.

        Returns False before the first sample. After a reset a DELETEALL goes first, so no
        stale part is left behind. The workpiece is drawn while there is a cutting load. The
        whole array goes out when what the still markers show changes (offset, direction,
        frame, loads) and at least every MARKER_REFRESH_PERIOD (for a viewer that starts
        later); in between only the moving markers, which keeps the conversion's hold on the
        GIL off the ticks (see linkage_markers). Above MARKER_SLICING_RATE the timer sends the
        same frame one marker per tick instead (what this one supersedes is dropped).
        """
        return self._publish_frame(None)

    def _publish_frame(self, sample):
        self._marker_slices = []
        frame = self._marker_frame(sample)
        for markers in frame or ():
            self._marker_publisher.publish(markers)
        return frame is not None

    def _marker_frame(self, sample=None):
        """
        Return the MarkerArrays of the latest published sample, in order (None: none).

        sample: the core's state (kinematics.state) at the stepper's present one, if known.
        """
        stepper = self._stepper
        stamp_ns = self._published_stamp_ns
        if stamp_ns is None:
            return None
        frame_id = self._values['frame_id']
        frame = []
        if self._clear_markers:
            frame.append(delete_all_marker_array(stamp_ns, frame_id))
            self._clear_markers = False
            self._still_markers = None
        still = (stepper.offset, stepper.input_speed < 0.0, frame_id, self._loads)
        now = time.monotonic()
        moving_only = (still == self._still_markers
                       and now - self._still_markers_sent < MARKER_REFRESH_PERIOD)
        if not moving_only:
            self._still_markers, self._still_markers_sent = still, now
        frame.append(linkage_marker_array(
            self._geometry, stepper.offset, stepper.input_angle, stamp_ns, frame_id,
            input_speed=stepper.input_speed, mechanism_state=sample, loads=self._loads,
            moving_only=moving_only))
        return frame

    def _report_stall(self, stepper, stamp_ns):
        """
        Say on /diagnostics (ERROR) and in the log when the motor stalls, and when it ends.

        The ERROR is repeated every second while it lasts, so monitors do not take it as stale.
        """
        reason = stepper.stall_reason if stepper.stalled else None
        changed = reason != self._stall_reason
        due = reason is not None and stamp_ns - self._stall_reported_ns >= _STALL_REPEAT_NS
        if not (changed or due):
            return
        self._stall_reason, self._stall_reported_ns = reason, stamp_ns
        if reason is None:
            level, text = DiagnosticStatus.OK, 'motor running: the stall is over'
            self.get_logger().info(text)
        else:
            level, text = DiagnosticStatus.ERROR, f'motor stalled: {reason}'
            if changed:
                self.get_logger().error(text)
        values = [KeyValue(key='stalled', value=str(reason is not None).lower()),
                  KeyValue(key='motor_torque', value=repr(stepper.motor_torque))]
        status = DiagnosticStatus(level=level, name=DRIVE_STATUS, hardware_id=SIM_NODE_NAME,
                                  message=text, values=values)
        message = DiagnosticArray(status=[status])
        message.header.stamp = stamp_message(stamp_ns)
        self._diagnostics_publisher.publish(message)

    def _publish_hold_status(self):
        """Publish the cutting-speed hold's state on /diagnostics: OK when exact, else WARN."""
        values = self._values
        answer = self._hold
        level = DiagnosticStatus.WARN if answer.problem else DiagnosticStatus.OK
        text = answer.problem or (
            f'holding {values["cutting_speed_definition"]} cutting speed '
            f'{values["cutting_speed_target"]:.6g} m/s with offset {answer.offset:.6g} m')
        key_values = [
            KeyValue(key='cutting_speed_target', value=repr(values['cutting_speed_target'])),
            KeyValue(key='cutting_speed_definition', value=values['cutting_speed_definition']),
            KeyValue(key='offset_command', value=repr(answer.offset)),
            KeyValue(key='reachable_min', value=repr(answer.reachable[0])),
            KeyValue(key='reachable_max', value=repr(answer.reachable[1]))]
        status = DiagnosticStatus(level=level, name=CUTTING_SPEED_STATUS,
                                  hardware_id=SIM_NODE_NAME, message=text, values=key_values)
        message = DiagnosticArray(status=[status])
        message.header.stamp = self.get_clock().now().to_msg()
        self._diagnostics_publisher.publish(message)

    def _pair_message(self, report, setting, setting_since_ns, target, definition):
        """Return a pair's report as the DiagnosticArray to publish."""
        key_values = [KeyValue(key=key, value=repr(value))
                      for key, value in report.values().items() if math.isfinite(value)]
        key_values.append(KeyValue(key='offset_steady', value=str(report.offset_steady).lower()))
        key_values.append(KeyValue(key='input_speed_steady',
                                   value=str(report.input_speed_steady).lower()))
        effort_theory, effort_theory_state = self._effort_theory(report, setting,
                                                                 setting_since_ns)
        key_values += effort_theory
        key_values.append(KeyValue(key='effort_theory', value=effort_theory_state))
        if target:
            measured_speed = report.measured[CUTTING_SPEED_FIGURES[definition]]
            key_values += [
                KeyValue(key='cutting_speed_target', value=repr(target)),
                KeyValue(key='cutting_speed_definition', value=definition),
                KeyValue(key='cutting_speed_measured', value=repr(measured_speed)),
                KeyValue(key='cutting_speed_error', value=repr(measured_speed / target - 1.0))]
        measured = report.measured
        steady = 'steady' if report.steady else 'NOT steady (ratios mixed)'
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK, name=STROKE_PAIR_STATUS, hardware_id=SIM_NODE_NAME,
            message=(f'TR {measured["time_ratio"]:.4f}, SR {measured["speed_ratio"]:.4f} '
                     f'(peak {measured["peak_speed_ratio"]:.4f}) at offset '
                     f'{report.coupling_offset:.6g} m, {report.input_speed:.6g} rad/s, '
                     f'{steady}'),
            values=key_values)
        message = DiagnosticArray(status=[status])
        message.header.stamp = stamp_message(report.stamp_ns)
        return message


def main(args=None):
    """Run the node until Ctrl-C or SIGTERM; exit 2 on bad start-up arguments or parameters."""
    try:
        init_rclpy(args)
    except RCLError as error:  # a malformed -p or params file, said by rcl
        print(f'{SIM_NODE_NAME}: cannot start: {rcl_error_text(error)}', file=sys.stderr)
        return 2
    node = executor = None
    try:
        with StopRequest() as stop:
            try:
                kind = executor_kind()  # QRM_ROS_EXECUTOR: events (default) or single
                node = ShaperSimNode()
            except ValueError as error:
                # Say which start-up value and why, no traceback (KinematicsError included).
                print(f'{SIM_NODE_NAME}: cannot start: {error}', file=sys.stderr)
                return 2
            executor = new_executor(kind)
            executor.add_node(node)
            spin_until_stopped(executor, stop)
    finally:
        if executor is not None:
            executor.shutdown()  # lets go of the node's entities before they are destroyed
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
