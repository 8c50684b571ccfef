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
Names the node, the recorder, the analysis, the main job and the tests share: one place each.

A recording made by one version must stay readable by the next, so these are part of the
package's interface: change one only with a migration.
"""

__all__ = ['CUTTING_SPEED_STATUS', 'DIAGNOSTICS_TOPIC', 'DRIVE_STATUS', 'DRIVES',
           'GEOMETRY_METADATA', 'JOINT_NAMES', 'JOINT_STATES_TOPIC', 'JOINT_STATE_TYPE',
           'LINKAGE_MARKERS_TOPIC', 'LINKAGE_MARKERS_TYPE', 'MOTOR_DRIVE', 'MOTOR_PREFIX',
           'PARAMETER_EVENTS_TOPIC', 'PARAMETERS_METADATA', 'RAM_TWIST_TOPIC',
           'RECORDER_NODE_NAME', 'ROBOT_DESCRIPTION_TOPIC', 'SIM_NODE_NAME',
           'SPEED_COMMAND_TOPIC', 'SPEED_DRIVE', 'STROKE_PAIR_STATUS', 'absolute_topic',
           'MACHINE_NAME', 'ROBOT_DESCRIPTION_TYPE', 'TF_MESSAGE_TYPE', 'TF_STATIC_TOPIC',
           'TF_TOPIC']

SIM_NODE_NAME = 'shaper_sim'
# The machine itself: the URDF's robot name and the hardware_id of the node's diagnostics
# (diagnostic_updater's convention: status names start with the node's name, hardware_id
# names the hardware).
MACHINE_NAME = 'qrm_shaper'
RECORDER_NODE_NAME = 'mcap_recorder'

# Order of the joints in every JointState the node publishes (and the URDF's joint names);
# the node publishes the crank radius's joint after them (PUBLISHED_JOINT_NAMES, below).
JOINT_NAMES = ('input_shaft_joint', 'flywheel_joint', 'lever_joint', 'ram_joint',
               'coupling_offset_joint')

# Topics, relative to the node's namespace where they are relative.
JOINT_STATES_TOPIC = 'joint_states'
RAM_TWIST_TOPIC = 'ram/twist'
SPEED_COMMAND_TOPIC = 'input_speed_cmd'
DIAGNOSTICS_TOPIC = '/diagnostics'
# rclpy's parameter events (rcl_interfaces/ParameterEvent): the recorder keeps them, so the
# analysis knows what changed mid-run.
PARAMETER_EVENTS_TOPIC = '/parameter_events'
JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'

# DiagnosticStatus.name of the node's per-stroke-pair report.
STROKE_PAIR_STATUS = f'{SIM_NODE_NAME}: stroke pair'
# DiagnosticStatus name of the drive's state (motor stalled or running).
DRIVE_STATUS = f'{SIM_NODE_NAME}: drive'
# DiagnosticStatus name of the cutting-speed hold (cutting_speed_target).
CUTTING_SPEED_STATUS = f'{SIM_NODE_NAME}: cutting speed'

# The motor drive's node parameters are its MotorDrive fields behind this prefix
# (motor_speed_stiffness, motor_max_torque); qrm_design's options follow them.
MOTOR_PREFIX = 'motor_'
# The node's drive parameter: an ideal speed source (the default, and what a recording made
# before the parameter existed ran on) or the motor (dynamics.md).
SPEED_DRIVE, MOTOR_DRIVE = DRIVES = ('speed', 'motor')

# MCAP metadata records the recorder writes and the analysis reads.
GEOMETRY_METADATA = 'qrm_ros.geometry'
PARAMETERS_METADATA = 'qrm_ros.parameters'


def absolute_topic(topic: str) -> str:
    """Return the topic as recorded from the root namespace ('joint_states' -> '/joint_states')."""
    return topic if topic.startswith('/') else '/' + topic


# visualization_msgs/MarkerArray of the linkage (frame, cranks, lever, ram, label).
LINKAGE_MARKERS_TOPIC = 'linkage_markers'
LINKAGE_MARKERS_TYPE = 'visualization_msgs/msg/MarkerArray'
# What robot_state_publisher publishes the URDF on (display.launch.py, shaper.rviz).
ROBOT_DESCRIPTION_TOPIC = '/robot_description'
ROBOT_DESCRIPTION_TYPE = 'std_msgs/msg/String'
# The links' transforms a recording carries beside the joint states (what
# robot_state_publisher would publish), for viewers that draw the URDF.
TF_TOPIC = '/tf'
TF_STATIC_TOPIC = '/tf_static'
TF_MESSAGE_TYPE = 'tf2_msgs/msg/TFMessage'

# The Foxglove WebSocket bridge's node name, and what it prints before the ws:// address once
# it listens (qrm_main --live reads the address from that line).
__all__ += ['BRIDGE_DEFAULT_PORT', 'BRIDGE_NODE_NAME', 'BRIDGE_SERVING_PREFIX']
BRIDGE_NODE_NAME = 'qrm_bridge'
BRIDGE_SERVING_PREFIX = f'{BRIDGE_NODE_NAME}: serving '
BRIDGE_DEFAULT_PORT = 8765  # the Foxglove app's default for a Foxglove WebSocket connection
BRIDGE_CLIENTS_STATUS = f'{BRIDGE_NODE_NAME}: clients'  # the bridge's status on /diagnostics
__all__ += ['BRIDGE_CLIENTS_STATUS']

# The stroke adjustment (added after the names above; recordings made before it have the
# five JOINT_NAMES only, and the analysis reads the crank radius's joint when present).
CRANK_RADIUS_JOINT = 'crank_radius_joint'
PUBLISHED_JOINT_NAMES = JOINT_NAMES + (CRANK_RADIUS_JOINT,)  # joint_states' order
# DiagnosticStatus name of the time-ratio hold (time_ratio_target).
TIME_RATIO_STATUS = f'{SIM_NODE_NAME}: time ratio'
__all__ += ['CRANK_RADIUS_JOINT', 'PUBLISHED_JOINT_NAMES', 'TIME_RATIO_STATUS']
