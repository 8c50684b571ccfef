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
Stand-in for shaper_sim in the recorder tests (a process of its own, no tests in here).

Same node name, topics and geometry parameters as the real node, but it waits until the given
number of subscribers matched every topic before publishing, so a recorder and a parallel test
subscriber see exactly the same messages. Prints 'published <n>' after each batch and keeps
serving (parameters, reliable resends) until SIGINT/SIGTERM.

    python stand_in_publisher.py COUNT RATE_HZ SUBSCRIBERS [--forever]
"""

import signal
import sys
import time


def main(argv):
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import TwistStamped
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    count, rate, subscribers = int(argv[0]), float(argv[1]), int(argv[2])
    forever = '--forever' in argv
    stop = []
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda *_: stop.append(1))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('shaper_sim')
    for name, value in [('coupling_radius', 0.025), ('crank_radius', 0.0505),
                        ('pivot_distance', 0.113), ('ram_height', 0.2), ('crank_phase', 0.0),
                        ('coupling_offset', 0.01), ('publish_rate', rate),
                        ('frame_id', 'shaper_base')]:
        node.declare_parameter(name, value)
    joints = node.create_publisher(JointState, 'joint_states', 10)
    twist = node.create_publisher(TwistStamped, 'ram/twist', 10)
    diagnostics = node.create_publisher(DiagnosticArray, '/diagnostics', 10)
    node.create_subscription(Float64, 'input_speed_cmd', lambda msg: None, 10)
    deadline = time.monotonic() + 20.0
    while not stop and time.monotonic() < deadline and min(
            p.get_subscription_count() for p in (joints, twist, diagnostics)) < subscribers:
        rclpy.spin_once(node, timeout_sec=0.02)
    published = 0
    period = 1.0 / rate
    next_time = time.monotonic()
    while not stop:
        if published < count or forever:
            stamp = node.get_clock().now().to_msg()
            joint_state = JointState()
            joint_state.header.stamp = stamp
            joint_state.header.frame_id = 'shaper_base'
            joint_state.name = ['input_shaft_joint', 'flywheel_joint', 'lever_joint',
                                'ram_joint', 'coupling_offset_joint']
            joint_state.position = [published * 0.01 + k / 7.0 for k in range(5)]
            joint_state.velocity = [published * -0.5 + k / 3.0 for k in range(5)]
            joints.publish(joint_state)
            message = TwistStamped()
            message.header = joint_state.header
            message.twist.linear.x = published / 9.0
            twist.publish(message)
            if published % 10 == 0:
                array = DiagnosticArray()
                array.header.stamp = stamp
                array.status = [DiagnosticStatus(level=DiagnosticStatus.OK, name='shaper_sim',
                                                 message=f'tick {published}',
                                                 values=[KeyValue(key='n',
                                                                  value=str(published))])]
                diagnostics.publish(array)
            published += 1
            if published == count:
                print(f'published {published}', flush=True)
            next_time += period
            rclpy.spin_once(node, timeout_sec=max(0.0, next_time - time.monotonic()))
        else:
            rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
