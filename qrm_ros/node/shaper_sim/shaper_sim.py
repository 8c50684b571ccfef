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

A thin adapter: ShaperStepper (qrm_ros.core.stepping.stepping) integrates the input angle and moves
the offset and the stroke; the kinematics core gives every other state in closed form. The rest
has a module of its own: what the parameters command (the stroke, the offset and its holds:
held_figures), the parameters, their rules and effects are data (shaper_parameters) that
parameter_services declares and guards through rclpy; the stroke-pair reports are measured
a step at a time after the ticks (stroke_pair_reports); what goes on /diagnostics is built in
shaper_diagnostics; marker_schedule says when the linkage markers go out. This module only
turns commands into stepper calls and states into messages. Run it with the shaper_sim
command (qrm_ros.cli.shaper_sim).
"""

from array import array
import math
import sys
import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
from qrm_ros.core.dynamics.chain import Loads, MassProperties, MotorDrive, parameter_names
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.stepping.stepper import Stepper
from qrm_ros.core.common.names import (DIAGNOSTICS_TOPIC, LINKAGE_MARKERS_TOPIC, SIM_NODE_NAME,
                                       SPEED_COMMAND_TOPIC)
from qrm_ros.core.stepping.stepping import ShaperStepper, wrap_angle
from qrm_ros.core.stepping.stroke_adjustment import StrokeRamp
from qrm_ros.core.stepping.speed_drive_sample import speed_drive_sample
from qrm_ros.core.dynamics.stroke_efforts import lever_radius_coefficient
from qrm_ros.node.shaper_sim.held_figures import HeldFigures
from qrm_ros.node.shaper_sim.marker_schedule import LinkageMarkerSchedule, MarkerScene
from qrm_ros.node.shaper_sim.parameter_services import ShaperParameterNode, WARNING_PERIOD
from qrm_ros.node.shaper_sim.shaper_diagnostics import DriveStatusReport
from qrm_ros.node.shaper_sim.shaper_parameters import shown
from qrm_ros.node.shaper_sim.state_publishers import MechanismStatePublishers, MIN_PUBLISHER_DEPTH
from qrm_ros.node.shaper_sim.stroke_pair_reports import StrokePairReports
from rclpy.qos import qos_profile_parameters
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

__all__ = ['ShaperSimNode']

# s: the longest another thread of the node (the motor kernel's loader, the theory's reply
# reader) may hold the GIL while a tick waits for it (Python's default is 5 ms).
GIL_SWITCH_INTERVAL = 1e-4
# Request queue of the node's own services: a burst of calls is answered, not dropped
# (the default service QoS keeps 10; rclpy's parameter services keep 1000, as here).
SERVICE_QOS = qos_profile_parameters


class ShaperSimNode(HeldFigures, ShaperParameterNode):
    """Steps the mechanism on a timer and publishes it; see the module docstring."""

    def __init__(self, **node_options):
        super().__init__(SIM_NODE_NAME, **node_options)
        self._pair_reports = None  # made once the diagnostics publisher is
        if sys.getswitchinterval() > GIL_SWITCH_INTERVAL:
            sys.setswitchinterval(GIL_SWITCH_INTERVAL)
        try:
            self._set_up()
        except Exception:
            self.destroy_node()  # a refused start-up leaves nothing on the graph
            raise

    def _set_up(self):
        self.declare_shaper_parameters()  # self._values, self._geometry
        values = self._values
        self._stepper: Optional[Stepper] = None  # made below, from the dynamics in force
        self.update_dynamics()
        # The stroke: from crank_radius's at start-up toward stroke_length (0: that one).
        self._stroke = StrokeRamp(self._geometry, values['max_crank_radius'],
                                  float(self._geometry.ram_stroke), values['stroke_rate_limit'])
        self._stroke.set_command(self.stroke_command)
        self._stepper = self._new_stepper(values['drive'])
        self._hold = None
        self._paused = False

        rate = values['publish_rate']
        self._state_publishers = MechanismStatePublishers(self, rate)
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, MIN_PUBLISHER_DEPTH)
        self._pair_reports = StrokePairReports(self._geometry, self._diagnostics_publisher,
                                               self.get_logger(), rate)
        self._drive_status = DriveStatusReport(self._diagnostics_publisher, self.get_logger())
        self._published_stamp_ns = None  # the markers draw the latest published sample
        self._markers = LinkageMarkerSchedule(
            self.create_publisher(MarkerArray, LINKAGE_MARKERS_TOPIC, MIN_PUBLISHER_DEPTH),
            self._geometry, rate, self._marker_scene)
        self.set_marker_rate(values['marker_rate'])
        self.create_subscription(Float64, SPEED_COMMAND_TOPIC, self._on_speed_command, 10)
        self.create_service(Trigger, '~/reset', self.on_reset, qos_profile=SERVICE_QOS)
        self.create_service(SetBool, '~/pause', self.on_pause, qos_profile=SERVICE_QOS)
        self.judge_parameter_changes()
        self._timer = self.create_timer(1.0 / rate, self.on_timer)
        if values['cutting_speed_target'] or values['time_ratio_target']:
            self.command_offset()
        self.get_logger().info(
            f'running: offset {values["coupling_offset"]} m, input speed '
            f'{values["input_speed"]} rad/s, {rate} Hz')

    # Parameters' effects (shaper_parameters: ParameterSpec.apply) -------------------------

    @property
    def speed_command(self):
        """The input speed command in force."""
        return self._stepper.speed_command

    def update_dynamics(self):
        """Take the mass, load and motor parameters in force (checked by their rules)."""
        values = self._values
        self._mass, self._loads, self._motor = (
            kind(**{field: values[name]
                    for field, name in zip(kind.field_names(), parameter_names(kind))})
            for kind in (MassProperties, Loads, MotorDrive))
        if isinstance(self._stepper, MotorStepper):
            self._stepper.set_dynamics(self._mass, self._loads, self._motor)

    def _new_stepper(self, drive: str) -> Stepper:
        values = self._values
        arguments = (values['input_speed'], values['coupling_offset'],
                     values['input_acceleration_limit'], values['offset_rate_limit'])
        if drive == 'motor':
            return MotorStepper(self._geometry, self._mass, self._loads, self._motor, *arguments,
                                stroke=self._stroke)
        return ShaperStepper(self._geometry, *arguments, stroke=self._stroke)

    def set_drive(self, drive):
        """Switch between the ideal speed source and the motor, keeping the state."""
        old = self._stepper
        new = self._new_stepper(drive)
        if old.stamp_ns is not None:
            new.restore(old.stamp_ns, old.input_angle, old.input_speed, old.offset)
        new.set_speed_command(old.speed_command)
        new.set_offset_command(old.offset_command)
        self._stepper = new
        self._pair_reports.clear()  # a pair spanning the switch would mix two drives

    # Commands and services ----------------------------------------------------------------

    def _on_speed_command(self, message):
        value = message.data
        limit = self._values['max_input_speed']
        if not math.isfinite(value) or abs(value) > limit:
            self.get_logger().warning(
                f'input_speed_cmd {value!r} rad/s ignored: allowed finite values in '
                f'[{shown(-limit)}, {shown(limit)}] rad/s (max_input_speed)',
                throttle_duration_sec=WARNING_PERIOD)
            return
        self.command_speed(value)

    def command_speed(self, input_speed):
        """Command the input speed; a held cutting speed follows it through the offset."""
        self._stepper.set_speed_command(input_speed)
        if self._values['cutting_speed_target']:
            self.command_offset()

    def on_reset(self, request, response):
        """Serve ~/reset: angle 0 at the input_speed, coupling_offset and stroke parameters."""
        del request
        speed, offset = self._values['input_speed'], self._values['coupling_offset']
        stroke = self.stroke_command
        self._stepper.reset(speed, offset, stroke_length=stroke)
        if self._values['cutting_speed_target'] or self._values['time_ratio_target']:
            self.command_offset()  # from the reset state, toward the held figure
        self._pair_reports.clear()
        self._markers.clear()  # DELETEALL before the next markers
        response.success = True
        response.message = (f'reset: input angle 0 rad, input speed {speed!r} rad/s, '
                            f'offset {offset!r} m, stroke {stroke!r} m')
        self.get_logger().info(response.message)
        return response

    def on_pause(self, request, response):
        """Serve ~/pause: hold the state (true) or go on from it (false)."""
        if request.data != self._paused:
            self._paused = request.data
            # No motion during the pause; the next sample continues from the held state.
            self._stepper.resync()
            self._pair_reports.clear()
        response.success = True
        response.message = 'paused' if self._paused else 'running'
        self.get_logger().info(response.message)
        return response

    @property
    def paused(self):
        return self._paused

    @property
    def stepper(self) -> Optional[Stepper]:
        return self._stepper

    @property
    def geometry(self):
        return self._geometry

    @property
    def mass(self):
        """The mass properties in force (MassProperties)."""
        return self._mass

    @property
    def loads(self):
        """The loads in force (Loads)."""
        return self._loads

    @property
    def motor(self):
        """The motor drive's parameters in force (MotorDrive)."""
        return self._motor

    @property
    def stroke_pairs(self):
        """The stroke-pair reports (their monitor, step budget and count)."""
        return self._pair_reports

    # Stepping and publishing --------------------------------------------------------------

    def on_timer(self):
        """Step to the node clock's time and publish (the timer's tick; paused: markers only)."""
        if self._paused:  # the held state, still drawn for a viewer that starts now
            self._markers.publish_if_due(self.get_clock().now().nanoseconds)
            self._pair_reports.run_steps(time.monotonic_ns())
            return
        stamp_ns = self.get_clock().now().nanoseconds
        if stamp_ns == 0:
            self.get_logger().info('use_sim_time is true and no /clock has arrived yet: '
                                   'waiting for it', throttle_duration_sec=WARNING_PERIOD)
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
        resets, cutoffs = stepper.time_resets, stepper.integration_cutoffs
        motor = isinstance(stepper, MotorStepper)
        stepper.integrate_to(stamp_ns)
        if stepper.integration_cutoffs != cutoffs:
            self.get_logger().warning(
                'the drive could not be integrated to this stamp within a bounded effort (a '
                'clock jump far ahead?): holding the state reached and continuing from the new '
                'time', throttle_duration_sec=WARNING_PERIOD)
            self._pair_reports.clear()
        if stepper.time_resets != resets:
            self.get_logger().warning(
                'node clock went back (simulated time restarted?): holding the state and '
                'continuing from the new time', throttle_duration_sec=WARNING_PERIOD)
            self._pair_reports.clear()
        stroke = stepper.stroke
        # The stepper's state, read once (a tick reads each several times).
        input_angle, input_speed = stepper.input_angle, stepper.input_speed
        offset, offset_rate = stepper.offset, stepper.offset_rate
        crank_radius = stroke.crank_radius
        radius_rate = stroke.crank_radius_rates()[0]
        # What drives each joint (N m, N), exact at the stamp. The speed drive supplies the
        # input torque the prescribed motion needs against inertia, gravity and the loads;
        # the motor stepper integrates the motion from the motor's torque and knows them.
        # The stroke screw's force is the lever torque's share through d(psi)/d(r).
        if motor:
            sample = stepper.mechanism_state()
            (flywheel_angle, flywheel_speed, lever_angle, lever_speed, ram_position,
             ram_velocity) = (sample.flywheel_angle, sample.flywheel_speed, sample.lever_angle,
                              sample.lever_speed, sample.ram_position, sample.ram_velocity)
            joint_efforts = array('d', stepper.efforts())
            joint_efforts.append(joint_efforts[2] * lever_radius_coefficient(
                stepper.geometry, flywheel_angle))
            self._drive_status.update(stepper, stamp_ns)
        else:
            # The workpiece fits the longer of the strokes in force and commanded (rules).
            sample, values = speed_drive_sample(stepper, self._mass, self._loads)
            (flywheel_angle, flywheel_speed, lever_angle, lever_speed, ram_position,
             ram_velocity) = values[:6]
            joint_efforts = array('d', values[6:])
        positions = array('d', (input_angle, wrap_angle(flywheel_angle), lever_angle,
                                ram_position, offset, crank_radius))
        velocities = array('d', (input_speed, flywheel_speed, lever_speed, ram_velocity,
                                 offset_rate, radius_rate))
        if not all(map(math.isfinite, positions + velocities + joint_efforts)):
            self.get_logger().error(
                f'non-finite state at {stamp_ns} ns not published: positions {positions}, '
                f'velocities {velocities}, efforts {joint_efforts}',
                throttle_duration_sec=WARNING_PERIOD)
            self._pair_reports.clear()  # a pair across a gap in publication is not steady
            return False
        self._state_publishers.publish(stamp_ns, self._values['frame_id'], positions,
                                       velocities, joint_efforts, ram_velocity)
        self._published_stamp_ns = stamp_ns
        # The speed drive's state where the core gave it: the markers need not recompute it.
        self._markers.publish_if_due(stamp_ns, None if motor else sample)
        reports = self._pair_reports
        speed_setting = reports.note_setting(stepper, self._mass, self._loads, self._motor,
                                             stamp_ns)
        completed = reports.monitor.collect(stamp_ns, ram_position, ram_velocity, offset,
                                            offset_rate, input_speed, joint_efforts[0],
                                            joint_efforts[4], crank_radius, radius_rate,
                                            speed_setting)
        if completed is not None:
            # What the report depends on is taken now, as it stands at the pair's end.
            reports.queue(completed, self._values['cutting_speed_target'],
                          self._values['cutting_speed_definition'],
                          self._values['time_ratio_target'])
        reports.run_steps(started_ns)
        return True

    def wait_for_pair_reports(self, timeout=None):
        """Report every pair completed so far, now, in this thread (for tests and tools)."""
        self._pair_reports.wait_for_all(timeout)

    @property
    def pair_reports_published(self):
        """How many stroke-pair statuses this node has published on /diagnostics."""
        return self._pair_reports.published

    def destroy_node(self):
        if self._pair_reports is not None:
            self._pair_reports.close()  # they go out before the publisher does
        return super().destroy_node()

    # Markers -------------------------------------------------------------------------------

    def set_marker_rate(self, rate):
        """Publish the linkage markers at rate Hz (0: stop), each right after a tick."""
        self._markers.set_rate(rate)

    def publish_markers(self):
        """Publish the mechanism as markers now (LinkageMarkerSchedule.publish_frame)."""
        return self._markers.publish_frame()

    def _marker_scene(self):
        """Return what the markers draw: the latest published sample (None before the first)."""
        stamp_ns = self._published_stamp_ns
        if stamp_ns is None:
            return None
        stepper = self._stepper
        return MarkerScene(stamp_ns, stepper.offset, stepper.input_angle, stepper.input_speed,
                           self._values['frame_id'], self._loads, stepper.geometry)
