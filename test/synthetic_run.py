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
Synthetic recorded runs for tests, written without ROS (mcap Writer + rosbags' serializer).

The joint states are the kinematics core's exact states along a schedule of offsets that the
offset actuator moves between at a constant rate, sampled at a fixed rate: what shaper_sim
publishes, but made in microseconds and independent of the node and the recorder.
"""

import json
import math

import numpy as np

from qrm_ros.analysis import recorded_run
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common import names
from qrm_ros.core.measurement.strokes import find_stroke_pairs, workpiece_edge_times

JOINT_NAMES = list(names.JOINT_NAMES)
PAPER = kin.Geometry.paper()
# Both signs of the offset and SR = 1 (-r r1 / h): the analysis tests' schedule.
SCHEDULE = [-0.015, -0.0111725663716814, 0.0, 0.008, 0.015]
# A crank phase off zero, so a drawing or a frame that forgot it would be seen.
PHASED = kin.Geometry(PAPER.coupling_radius, PAPER.crank_radius, PAPER.pivot_distance,
                      PAPER.ram_height, 0.3)
# A run with efforts on its joint states, for the animation's tests.
EFFORTS_SCHEDULE = dict(geometry=PHASED, offsets=[0.0, 0.012], hold=1.5)


def schedule_states(geometry, offsets, hold=4.0, offset_rate=0.01, input_speed=2 * math.pi,
                    rate=100.0, start_angle=0.3):
    """Return (time, input_angle, offset, offset_velocity, state) along an offset schedule."""
    knots_t, knots_d = [0.0], [offsets[0]]
    for previous, following in zip(offsets, offsets[1:]):
        knots_t += [knots_t[-1] + hold, knots_t[-1] + hold + abs(following - previous)
                    / offset_rate]
        knots_d += [previous, following]
    knots_t.append(knots_t[-1] + hold)
    knots_d.append(offsets[-1])
    time = np.arange(0.0, knots_t[-1], 1.0 / rate)
    offset = np.interp(time, knots_t, knots_d)
    slope = np.diff(knots_d) / np.diff(knots_t)
    offset_velocity = slope[np.clip(np.searchsorted(knots_t, time, side='right') - 1, 0,
                                    slope.size - 1)]
    input_angle = start_angle + input_speed * time
    state = kin.state(geometry, offset, input_angle, input_speed, 0.0, offset_velocity)
    wrapped = np.mod(input_angle + math.pi, 2 * math.pi) - math.pi
    return time, wrapped, offset, offset_velocity, state


def schedule_efforts(geometry, mass, loads, offset, input_angle, input_speed, offset_velocity,
                     state):
    """Return the joint efforts (n, 5) shaper_sim publishes for these states (speed drive)."""
    load = dyn.ram_load_force(loads, state.ram_position, state.ram_velocity,
                              geometry.ram_stroke)
    efforts = dyn.efforts(geometry, mass, offset, input_angle, input_speed, 0.0,
                          offset_velocity, 0.0, load)
    return np.stack(efforts, axis=1)


def write_run(path, geometry, offsets, with_geometry=True, joint_states_topic='/joint_states',
              start_ns=1_700_000_000_000_000_000, chunk_size=256 * 1024, data_crc=False,
              mass=None, loads=None, effort=None, **schedule):
    """
    Write a synthetic run as a ros2-profile MCAP file; return the number of messages.

    With mass and loads (dynamics.MassProperties, Loads), the messages carry the efforts and
    the file the parameters metadata, as the node and the recorder write them; the ramps'
    offset acceleration is taken as 0 (the node's speed drive does the same). Otherwise
    ``effort``: None (no efforts, as the golden logs) or time (s) -> the five joints' efforts.
    """
    from mcap.writer import Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    type_name = 'sensor_msgs/msg/JointState'
    JointState = store.types[type_name]
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']
    time, input_angle, offset, offset_velocity, state = schedule_states(geometry, offsets,
                                                                        **schedule)
    speed = schedule.get('input_speed', 2 * math.pi)
    if mass is not None:
        efforts = schedule_efforts(geometry, mass, loads, offset, input_angle, speed,
                                   offset_velocity, state)
    else:
        efforts = np.empty((time.size, 0))
    with open(path, 'wb') as handle:
        writer = Writer(handle, chunk_size=chunk_size, enable_data_crcs=data_crc)
        writer.start(profile='ros2', library='qrm_ros test synthetic_run')
        text, _ = store.generate_msgdef(type_name, ros_version=2)
        schema = writer.register_schema(type_name, 'ros2msg', text.encode())
        channel = writer.register_channel(joint_states_topic, 'cdr', schema)
        if with_geometry:
            writer.add_metadata('qrm_ros.geometry', {k: repr(float(v)) for k, v in
                                                     geometry.as_dict().items()})
        if mass is not None:
            parameters = {**mass.as_dict(), **loads.as_dict(), **geometry.as_dict()}
            writer.add_metadata(names.PARAMETERS_METADATA,
                                {k: json.dumps(float(v)) for k, v in parameters.items()})
        for i, t in enumerate(time):
            stamp_ns = start_ns + int(round(t * 1e9))
            message = JointState(
                header=Header(stamp=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
                              frame_id='shaper_base'),
                name=JOINT_NAMES,
                position=np.array([input_angle[i], state.flywheel_angle[i],
                                   state.lever_angle[i], state.ram_position[i], offset[i]]),
                velocity=np.array([speed, state.flywheel_speed[i], state.lever_speed[i],
                                   state.ram_velocity[i], offset_velocity[i]]),
                effort=efforts[i] if effort is None else np.array(effort(t), dtype=float))
            data = store.serialize_cdr(message, type_name)
            writer.add_message(channel, log_time=stamp_ns + 250_000, publish_time=stamp_ns,
                               data=bytes(data), sequence=i)
        writer.finish()
    return len(time)


def dense_revolution(geometry, mass, loads, offset, input_speed, samples=400001):
    """
    Sample one revolution at a steady speed densely: (times, input torque, offset force).

    The ideal speed drive's efforts at each sample, its load from the sample's own motion:
    the brute-force reference the exact per-pair figures are checked against.
    """
    period = 2 * math.pi / abs(input_speed)
    times = np.linspace(0.0, period, samples)
    motion = kin.state(geometry, offset, input_speed * times, input_speed)
    load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                              geometry.ram_stroke)
    result = dyn.efforts(geometry, mass, offset, input_speed * times, input_speed,
                         external_ram_force=load)
    return times, result.input_torque, result.offset_force


def samples_for(offsets, input_speed=2 * math.pi, **kwargs):
    """Return the analysis's Samples of the paper's machine along a schedule of offsets."""
    time, angle, offset, offset_velocity, state = schedule_states(
        PAPER, offsets, input_speed=input_speed, **kwargs)
    return recorded_run.Samples(time, angle, np.full_like(time, input_speed),
                                state.flywheel_angle, state.flywheel_speed, state.ram_position,
                                state.ram_velocity, offset, offset_velocity)


def made_up_efforts(time):
    """Return efforts (N m, N) of the five joints at time (s): made up, distinct at each."""
    return [40.0 * math.sin(3.0 * time) + 5.0, 0.0, 0.0, -12.0 * time, 0.0]


def write_truncated_run(folder, kept_fraction=0.8):
    """Write a two-offset run in small chunks and a copy cut short; return the copy's path."""
    whole = folder / 'run.mcap'
    write_run(whole, PAPER, [0.0, 0.01], hold=3.0, chunk_size=16 * 1024)
    data = whole.read_bytes()
    cut = folder / 'cut.mcap'
    cut.write_bytes(data[:int(len(data) * kept_fraction)])
    return cut


def sampled_speed_drive(offset, rate, phase=0.0, duration=3.5, loads=None, speed=2 * math.pi,
                        mass=None):
    """
    Return the ideal speed drive at offset sampled at rate (Hz), from phase (of a step) on.

    (time, the joints' efforts, the stroke pairs and the workpiece edges found in the samples).
    """
    loads = dyn.Loads.small_shaper() if loads is None else loads
    mass = dyn.MassProperties.small_shaper() if mass is None else mass
    t = np.arange(0.0, duration, 1.0 / rate) + phase / rate
    angle = speed * t + 0.3
    motion = kin.state(PAPER, offset, angle, speed)
    load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                              PAPER.ram_stroke)
    joint = dyn.efforts(PAPER, mass, offset, angle, speed, external_ram_force=load)
    pairs = find_stroke_pairs(t, motion.ram_position, motion.ram_velocity)
    edges = workpiece_edge_times(t, motion.ram_position, motion.ram_velocity,
                                 pairs.cutting_start, pairs.cutting_end, loads.cutting_length)
    return t, joint, pairs, edges
