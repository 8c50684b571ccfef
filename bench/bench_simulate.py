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
qrm_simulate's speed against its floor: the same messages serialized and written, nothing else.

The floor, per tick: fill a JointState (six joints' positions, velocities, efforts) and a
TwistStamped, serialize both with rclpy's serialize_message and write them with the mcap
Writer (zstd chunks of the simulator's size), into a file; and, since the simulator writes
them too (as the recorder does), the moving links' TFMessage (six transforms) filled and
serialized by the same library call the simulator uses (rosbags' serialize_cdr: tf2_msgs
has no rclpy type here) and written; and once a stroke pair (every 100 ticks at the node's
default 1 rev/s and 100 Hz) the pair's /diagnostics status, a message the simulator wrote
in a short run, serialized as the simulator does (typestore.exact_cdr) and written. The
two-message floor of the issue (joint states and twists alone) is measured as well. The
simulator, per tick: the whole node tick (stepping, efforts, stroke measurement and
reports, the messages), serialization and writing, with the node's default 100 Hz and
offset +10 mm, for each drive. Ticks per second of the loop (the set-up apart: the
compiled forms are loaded once before the runs), interleaved over repeats; medians and
their spread; the ratio simulator / floor (goal >= 0.7 for the speed drive) and how long an
hour of machine time at 100 Hz takes.

--breakdown says where a speed-drive tick's CPU time goes instead: the run again with one
part more left out each time (the stroke-pair measurement, the /tf, the serializing and
writing, the kinematics and efforts; each left out by replacing its call), the floors beside.

    python3 dev.py run python bench/bench_simulate.py [--repeats 5] [--seconds 120]
    python3 dev.py run python bench/bench_simulate.py --breakdown [--repeats 3] [--seconds 200]
"""

import argparse
from array import array
import math
import os
import statistics
import tempfile
import time

from geometry_msgs.msg import TwistStamped
from mcap.writer import CompressionType, Writer
from rclpy.serialization import serialize_message
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import JointState

from qrm_ros.core.dynamics.drive_kernel_loading import COMPILED_DRIVE_KERNEL
from qrm_ros.core.common.names import PUBLISHED_JOINT_NAMES, TF_MESSAGE_TYPE
from qrm_ros.node.shaper_sim import shaper_sim
from qrm_ros.node.offline.offline_sim import RecordingPublisher, Simulation
from qrm_ros.node.offline.scenario import scenario_from_mapping
from qrm_ros.recording.machine_channels import MachineChannels
from qrm_ros.recording.mcap_run_file import CHUNK_SIZE_BYTES
from qrm_ros.recording.typestore import exact_cdr

PERIOD_NS = 10_000_000
# Ticks of a stroke pair at the node's default input speed (1 rev/s) and rate (100 Hz).
PAIR_TICKS = 100
DIAGNOSTICS_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'


def _tf_message(store):
    """Return a TFMessage of rosbags' types with as many transforms as moving joints."""
    types = store.types
    return types[TF_MESSAGE_TYPE](transforms=[types['geometry_msgs/msg/TransformStamped'](
        header=types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id='parent'),
        child_frame_id=name, transform=types['geometry_msgs/msg/Transform'](
            translation=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
            rotation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)))
        for name in PUBLISHED_JOINT_NAMES])


def _stroke_pair_status(folder):
    """Return a stroke pair's /diagnostics message as the simulator writes it (a short run)."""
    written = []
    write_exact = Simulation._write_exact

    def kept(simulation, type_name, channel, message):
        if type_name == DIAGNOSTICS_TYPE:
            written.append(message)
        write_exact(simulation, type_name, channel, message)
    Simulation._write_exact = kept
    try:
        path = os.path.join(folder, 'status.mcap')
        Simulation(scenario_from_mapping({'duration': 3.0, 'parameters': {
            'coupling_offset': 0.01}}), path).run()
        os.unlink(path)
    finally:
        Simulation._write_exact = write_exact
    return written[-1]


def floor(path, ticks, transforms=True, status=None):
    """
    Return the ticks per second of filling, serializing and writing the messages.

    status: a stroke pair's /diagnostics message, written once a pair (every PAIR_TICKS) as
    the simulator writes it (exact_cdr), or None (the two-message floor: not written).
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    tf_message = _tf_message(store)
    with open(path, 'wb') as stream:
        # Chunks of the simulator's size (the run file's cap), zstd as its default.
        writer = Writer(stream, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.ZSTD)
        writer.start('ros2', 'bench')
        schema = writer.register_schema('sensor_msgs/msg/JointState', 'ros2msg', b'')
        joints = writer.register_channel('/joint_states', 'cdr', schema)
        twists = writer.register_channel('/ram/twist', 'cdr', schema)
        tf = writer.register_channel('/tf', 'cdr', schema)
        diagnostics = writer.register_channel('/diagnostics', 'cdr', schema)
        joint_state, twist = JointState(name=list(PUBLISHED_JOINT_NAMES)), TwistStamped()
        started, cpu_started = time.perf_counter(), time.process_time()
        for tick in range(1, ticks + 1):
            stamp = tick * PERIOD_NS
            seconds, nanoseconds = divmod(stamp, 1_000_000_000)
            angle = tick * 0.0628
            joint_state.header.stamp.sec, joint_state.header.stamp.nanosec = seconds, nanoseconds
            joint_state.header.frame_id = 'shaper_base'
            joint_state.position = array('d', (angle, angle, 0.1, 0.05, 0.01, 0.05))
            joint_state.velocity = array('d', (6.28, 5.1, 0.7, 0.3, 0.0, 0.0))
            joint_state.effort = array('d', (1.5, 1.2, 3.4, 10.0, 35.0, 0.0))
            writer.add_message(joints, stamp, serialize_message(joint_state), stamp)
            twist.header.stamp.sec, twist.header.stamp.nanosec = seconds, nanoseconds
            twist.header.frame_id = 'shaper_base'
            twist.twist.linear.x = 0.3
            writer.add_message(twists, stamp, serialize_message(twist), stamp)
            if transforms:
                for index, transform in enumerate(tf_message.transforms):
                    transform.header.stamp.sec = seconds
                    transform.header.stamp.nanosec = nanoseconds
                    transform.transform.translation.x = 0.01 * index
                    transform.transform.rotation.z = math.sin(0.5 * angle)
                    transform.transform.rotation.w = math.cos(0.5 * angle)
                writer.add_message(tf, stamp, bytes(store.serialize_cdr(
                    tf_message, TF_MESSAGE_TYPE)), stamp)
            if status is not None and tick % PAIR_TICKS == 0:
                status.header.stamp.sec, status.header.stamp.nanosec = seconds, nanoseconds
                writer.add_message(diagnostics, stamp, exact_cdr(status, DIAGNOSTICS_TYPE),
                                   stamp)
        writer.finish()
        return (ticks / (time.perf_counter() - started),
                ticks / (time.process_time() - cpu_started))


def simulated(path, seconds, drive):
    """Return the ticks per second (wall, CPU) of the simulator's loop on `seconds`."""
    scenario = scenario_from_mapping({'duration': seconds, 'parameters': {
        'coupling_offset': 0.01, 'drive': drive}})
    simulation = Simulation(scenario, path)
    cpu_started = time.process_time()  # the run, finishing the file included
    summary = simulation.run()
    return (summary.ticks / summary.loop_seconds,
            summary.ticks / (time.process_time() - cpu_started))


# What --breakdown leaves out, one more part in each run: (label, how it is left out).
LEFT_OUT = ('the stroke-pair measurement and reports', 'the /tf',
            'the serializing and writing', 'the kinematics and efforts')


def _leave_out(simulation, part, undo):
    """Replace the call of one part of the speed drive's tick by a no-op (undo: put back)."""
    node = simulation.node
    if part == 0:  # no samples kept: no pair is ever completed
        node.stroke_pairs.monitor.collect = lambda *arguments: None
    elif part == 1:
        undo.append((MachineChannels, 'joint_state_values', MachineChannels.joint_state_values))
        MachineChannels.joint_state_values = lambda *arguments: None
    elif part == 2:
        for publisher in node.publishers:
            if isinstance(publisher, RecordingPublisher):
                publisher.write = None
    else:  # the speed drive's sample: its state and efforts, as at the first tick
        sample = shaper_sim.speed_drive_sample(node.stepper, node.mass, node.loads)
        undo.append((shaper_sim, 'speed_drive_sample', shaper_sim.speed_drive_sample))
        shaper_sim.speed_drive_sample = lambda *arguments: sample


def breakdown(folder, seconds, repeats):
    """Print the CPU time (us) of a speed-drive tick with ever more parts left out."""
    labels = ['the whole tick'] + [f'... without {label}' for label in LEFT_OUT]
    times = {label: [] for label in labels + ['floor', 'floor_no_tf']}
    path = os.path.join(folder, 'breakdown.mcap')
    status = _stroke_pair_status(folder)
    for _ in range(repeats):
        for index, label in enumerate(labels):
            simulation = Simulation(scenario_from_mapping({'duration': seconds, 'parameters': {
                'coupling_offset': 0.01, 'drive': 'speed'}}), path)
            undo = []
            try:
                for part in range(index):
                    _leave_out(simulation, part, undo)
                cpu_started = time.process_time()
                ticks = simulation.run().ticks
                times[label].append(1e6 * (time.process_time() - cpu_started) / ticks)
            finally:
                for owner, name, value in undo:
                    setattr(owner, name, value)
            os.unlink(path)
        for name in ('floor', 'floor_no_tf'):
            full = name == 'floor'
            times[name].append(1e6 / floor(path, round(seconds * 100), full,
                                           status if full else None)[1])
            os.unlink(path)
    before = None
    for label, values in times.items():
        median = statistics.median(values)
        step = f'  ({before - median:5.1f} us less)' if before is not None else ''
        print(f'{label:52s} {median:6.1f} us CPU a tick ({min(values):.1f}..{max(values):.1f})'
              + (step if label in labels else ''))
        before = median if label in labels else before


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--seconds', type=float, default=120.0,
                        help='machine time per simulated run [s] (motor: a quarter)')
    parser.add_argument('--breakdown', action='store_true',
                        help='where a speed-drive tick\'s time goes (see the docstring)')
    args = parser.parse_args()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
    # The drives' compiled forms, loaded once per process (0.3-1 s; a first run's own load is
    # set-up, as the node's start), before any run is timed.
    COMPILED_DRIVE_KERNEL.start_loading()
    COMPILED_DRIVE_KERNEL.loaded.wait(60.0)
    if args.breakdown:
        with tempfile.TemporaryDirectory() as folder:
            breakdown(folder, args.seconds, args.repeats)
        return
    rates = {'floor': [], 'floor_no_tf': [], 'speed': [], 'motor': []}
    cpu_rates = {name: [] for name in rates}
    with tempfile.TemporaryDirectory() as folder:
        status = _stroke_pair_status(folder)
        for repeat in range(args.repeats):
            for name in rates:
                path = os.path.join(folder, f'{name}_{repeat}.mcap')
                if name.startswith('floor'):
                    full = name == 'floor'
                    rate = floor(path, round(args.seconds * 100), full, status if full else None)
                else:
                    rate = simulated(path, args.seconds / (4 if name == 'motor' else 1), name)
                rates[name].append(rate[0])
                cpu_rates[name].append(rate[1])
                os.unlink(path)
            print(f'repeat {repeat + 1}: ' + ', '.join(
                f'{name} {values[-1]:.0f} ticks/s' for name, values in rates.items()),
                flush=True)
    # Wall time is what a user waits; CPU time (process_time) is what the work costs, which a
    # machine shared with other work (its load) disturbs less.
    for clock, found in (('wall', rates), ('CPU', cpu_rates)):
        median = {name: statistics.median(values) for name, values in found.items()}
        for name, values in found.items():
            print(f'{clock:4s} {name:11s} median {median[name]:8.0f} ticks/s ({min(values):.0f}'
                  f'..{max(values):.0f}); an hour at 100 Hz in {360000 / median[name]:.1f} s')
        for drive in ('speed', 'motor'):
            for floor_name in ('floor', 'floor_no_tf'):
                ratios = [d / f for d, f in zip(found[drive], found[floor_name])]
                print(f'{clock:4s} {drive} drive / {floor_name}: median '
                      f'{statistics.median(ratios):.3f} ({min(ratios):.3f}..{max(ratios):.3f})')


if __name__ == '__main__':
    main()
