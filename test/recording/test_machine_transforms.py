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
The machine in a run file: the recorded transforms are the URDF's forward kinematics (yourdfpy,
not our own) posed by the core's joint values, and a run file carrying them still reads the
same in our reader, qrm_analyze, rosbags and Foxglove's own readers (@mcap/core,
@foxglove/rosmsg, @foxglove/rosmsg2-serialization, run by node when it is installed).
"""

import fcntl
import hashlib
import json
import math
import os
import shutil
import subprocess

import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores
from scipy.spatial.transform import Rotation
import yaml

from qrm_ros.cli import qrm_analyze
from qrm_ros.core import kinematics as kin
from qrm_ros.core.common.names import (GEOMETRY_METADATA, JOINT_NAMES, JOINT_STATE_TYPE,
                                       JOINT_STATES_TOPIC, PUBLISHED_JOINT_NAMES,
                                       ROBOT_DESCRIPTION_TOPIC, TF_STATIC_TOPIC, TF_TOPIC)
from qrm_ros.recording.bag_reader import open_run
from qrm_ros.recording.machine_channels import MachineChannels
from qrm_ros.recording.machine_transforms import (fixed_transforms, MachineMessages,
                                                  moving_transforms)
from qrm_ros.recording.mcap_run_file import COMPRESSIONS, McapRunFile
from qrm_ros.recording.urdf_model import BASE_LINK, urdf_text, write_urdf
from repo_paths import TEST_DATA, TEST_FOLDER

yourdfpy = pytest.importorskip('yourdfpy')

GEOMETRIES = {
    'paper': kin.Geometry.paper(),
    'phased': kin.Geometry(0.03, 0.07, 0.16, ram_height=0.35, crank_phase=0.4),
    'short_stroke': kin.Geometry(0.02, 0.01, 0.12, ram_height=0.15, crank_phase=-2.0),
}
GOLDEN = os.path.join(TEST_DATA, 'steady_positive_offset.mcap')
FOXGLOVE_READER = os.path.join(TEST_FOLDER, 'recording', 'foxglove_reader')
STORE = get_typestore(Stores.ROS2_JAZZY)


def _wrapped(angle):
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _published(geometry, offset, input_angle):
    """The joint values the node publishes for this state (the core's kinematics)."""
    state = kin.state(geometry, offset, input_angle, 1.0)
    return {'input_shaft_joint': _wrapped(input_angle),
            'flywheel_joint': _wrapped(float(state.flywheel_angle)),
            'lever_joint': float(state.lever_angle), 'ram_joint': float(state.ram_position),
            'coupling_offset_joint': offset, 'crank_radius_joint': geometry.crank_radius}


def _matrix(transform):
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_quat(transform.rotation).as_matrix()
    matrix[:3, 3] = transform.translation
    return matrix


@pytest.mark.parametrize('name', sorted(GEOMETRIES))
def test_transforms_are_the_urdfs_forward_kinematics(name, tmp_path):
    geometry = GEOMETRIES[name]
    path = str(tmp_path / 'model.urdf')
    write_urdf(path, geometry)
    model = yourdfpy.URDF.load(path, build_scene_graph=True, load_meshes=False)
    rng = np.random.default_rng(11)
    r1 = geometry.coupling_radius
    worst_position = worst_rotation = 0.0
    for input_angle, offset in zip(rng.uniform(-20.0, 20.0, 60),
                                   rng.uniform(-0.95, 0.95, 60) * r1):
        values = _published(geometry, float(offset), float(input_angle))
        model.update_cfg(values)
        transforms = fixed_transforms(geometry) + moving_transforms(geometry, values)
        assert sorted(t.child for t in transforms) == sorted(set(model.link_map) - {BASE_LINK})
        by_child = {t.child: t for t in transforms}

        def in_base(link):
            if link == BASE_LINK:
                return np.eye(4)
            transform = by_child[link]
            return in_base(transform.parent) @ _matrix(transform)
        for link in by_child:
            expected = model.get_transform(link, BASE_LINK)
            ours = in_base(link)
            worst_position = max(worst_position, np.max(np.abs(ours[:3, 3] - expected[:3, 3])))
            worst_rotation = max(worst_rotation,
                                 np.max(np.abs(ours[:3, :3] - expected[:3, :3])))
            # Each transform is its joint's alone: the child in its parent's frame.
            parent = by_child[link].parent
            assert np.allclose(_matrix(by_child[link]), model.get_transform(link, parent),
                               rtol=0.0, atol=1e-12)
        for transform in transforms:
            assert np.linalg.norm(transform.rotation) == pytest.approx(1.0, abs=1e-15)
    assert worst_position <= 1e-9  # m
    assert worst_rotation <= 1e-9


def _joint_state(stamp_ns, names, positions):
    types = STORE.types
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    message = types[JOINT_STATE_TYPE](
        header=types['std_msgs/msg/Header'](stamp=types['builtin_interfaces/msg/Time'](
            sec=sec, nanosec=nanosec), frame_id=''),
        name=list(names), position=np.array(positions, dtype=float),
        velocity=np.zeros(len(names)), effort=np.zeros(len(names)))
    return bytes(STORE.serialize_cdr(message, JOINT_STATE_TYPE))


def _decoded(data):
    """(parent, child, translation, rotation, stamp ns) of each transform of a TFMessage."""
    message = STORE.deserialize_cdr(data, 'tf2_msgs/msg/TFMessage')
    return [(t.header.frame_id, t.child_frame_id,
             (t.transform.translation.x, t.transform.translation.y, t.transform.translation.z),
             (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
              t.transform.rotation.w),
             t.header.stamp.sec * 1_000_000_000 + t.header.stamp.nanosec)
            for t in message.transforms]


def test_a_recorded_joint_state_gives_its_transforms_stamped_as_it_is():
    geometry = GEOMETRIES['phased']
    messages = MachineMessages(geometry)
    values = _published(geometry, 0.01, 2.0)
    stamp = 1_700_000_000_123_456_789
    data = _joint_state(stamp, JOINT_NAMES[::-1], [values[n] for n in JOINT_NAMES[::-1]])
    expected = moving_transforms(geometry, values)
    assert _decoded(messages.transforms(data)) == [
        (t.parent, t.child, t.translation, t.rotation, stamp) for t in expected]
    assert messages.joint_state_stamp(data) == stamp
    assert [(p, c, x, q) for p, c, x, q, _ in _decoded(messages.static_transforms(5))] == [
        tuple(t) for t in fixed_transforms(geometry)]
    text = STORE.deserialize_cdr(messages.robot_description(), 'std_msgs/msg/String').data
    assert text == urdf_text(geometry)
    # Nothing for what a viewer would draw wrong.
    assert messages.transforms(b'\x00\x01\x00') is None
    assert messages.transforms(_joint_state(stamp, JOINT_NAMES[:4],
                                            [values[n] for n in JOINT_NAMES[:4]])) is None
    assert messages.transforms(_joint_state(stamp, JOINT_NAMES,
                                            [math.nan] + [0.0] * 4)) is None


def test_a_writer_holding_the_values_gets_the_decoded_joint_states_transforms():
    """joint_transforms (the simulator's, no decoding) is transforms() of the same message."""
    geometry = GEOMETRIES['phased']
    messages = MachineMessages(geometry)
    for offset, angle in ((0.01, 2.0), (-0.02, -3.1), (0.0, 0.4)):
        values = _published(geometry, offset, angle)
        stamp = 1_700_000_000_123_456_789 + round(angle * 1e9)
        sec, nanosec = divmod(stamp, 1_000_000_000)
        for names in (PUBLISHED_JOINT_NAMES, PUBLISHED_JOINT_NAMES[::-1],
                      PUBLISHED_JOINT_NAMES[:-1]):
            positions = [values[name] for name in names]
            data = _joint_state(stamp, names, positions)
            assert messages.joint_transforms(sec, nanosec, names, positions) == (
                messages.transforms(data)) is not None
    assert messages.joint_transforms(0, 0, JOINT_NAMES[:4], [0.0] * 4) is None
    assert messages.joint_transforms(0, 0, PUBLISHED_JOINT_NAMES,
                                     [math.inf] + [0.0] * 5) is None


def _copy_with_machine(source, target, geometry_after):
    """Rewrite a recorded run as the recorder now writes it: the geometry comes late."""
    run = open_run(source)
    run_file = McapRunFile(target, COMPRESSIONS['zstd'], 1_000_000_000)
    machine = MachineChannels(run_file)
    geometry = kin.Geometry(**{name: float(value) for name, value
                               in run.metadata[GEOMETRY_METADATA].items()})
    channels, joint_states = {}, 0
    for message in run.messages():
        if message.topic not in channels:
            channel = run.channel(message.topic)
            run_file.add_schema(message.schema_name, run.schema_text(message.schema_name))
            channels[message.topic] = run_file.add_channel(
                message.topic, message.schema_name, channel.metadata['offered_qos_profiles'],
                channel.metadata['topic_type_hash'])
        run_file.add_message(channels[message.topic], message.log_time, message.publish_time,
                             message.data)
        if message.topic == '/' + JOINT_STATES_TOPIC:
            machine.joint_state(message.log_time, message.publish_time, message.data)
            joint_states += 1
            if joint_states == geometry_after:
                machine.start(geometry, message.log_time)
    for name, data in run.metadata.items():
        if name != 'rosbag2':
            run_file.add_metadata(name, data)
    run_file.finish()
    return geometry


@pytest.fixture(scope='module')
def with_machine(tmp_path_factory):
    path = str(tmp_path_factory.mktemp('machine') / 'run.mcap')
    geometry = _copy_with_machine(GOLDEN, path, geometry_after=40)
    return path, geometry


def test_our_reader_sees_the_machine_from_the_first_joint_state(with_machine):
    path, geometry = with_machine
    run = open_run(path)
    assert not run.truncated
    topics = run.topics()
    assert topics[TF_TOPIC] == topics[TF_STATIC_TOPIC] == 'tf2_msgs/msg/TFMessage'
    assert topics[ROBOT_DESCRIPTION_TOPIC] == 'std_msgs/msg/String'
    latched = yaml.safe_load(run.channel_metadata(TF_STATIC_TOPIC)['offered_qos_profiles'])
    assert latched[0]['durability'] == 'transient_local'
    joint_states = list(run.messages([JOINT_STATES_TOPIC]))
    transforms = list(run.messages([TF_TOPIC]))
    assert len(transforms) == len(joint_states) == run.message_count(TF_TOPIC)
    (description,) = run.messages([ROBOT_DESCRIPTION_TOPIC])
    (static,) = run.messages([TF_STATIC_TOPIC])
    assert description.log_time == static.log_time == joint_states[0].log_time
    assert STORE.deserialize_cdr(description.data, 'std_msgs/msg/String').data == urdf_text(
        geometry)
    for joint_state, transform in zip(joint_states, transforms):
        assert transform.log_time == joint_state.log_time
        decoded = STORE.deserialize_cdr(joint_state.data, JOINT_STATE_TYPE)
        values = dict(zip(decoded.name, decoded.position))
        stamp = decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec
        assert _decoded(transform.data) == [(t.parent, t.child, t.translation, t.rotation, stamp)
                                            for t in moving_transforms(geometry, values)]
    log_times = [message.log_time for message in run.messages()]
    assert log_times == sorted(log_times)


def test_qrm_analyze_reads_it_as_before(with_machine, tmp_path, capsys):
    path, _ = with_machine
    documents = []
    for source in (GOLDEN, path):
        output = tmp_path / (os.path.basename(os.path.dirname(source)) + '.json')
        assert qrm_analyze.main([source, '--json', str(output)]) == 0, capsys.readouterr().err
        document = json.loads(output.read_text())
        document.pop('file', None)
        documents.append(document)
    assert documents[0] == documents[1]


def test_rosbags_reads_it(with_machine, tmp_path):
    from pathlib import Path
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2.storage_mcap import McapReader
    path, _ = with_machine
    ours = {topic: [m.data for m in open_run(path).messages([topic])]
            for topic in open_run(path).topics()}
    storage = McapReader(Path(path))
    storage.open()
    try:
        read = {}
        for connection, _, data in storage.messages(storage.connections):
            read.setdefault(connection.topic, []).append(bytes(data))
    finally:
        storage.close()
    assert read == ours
    # A rosbag2 folder made from the file's own rosbag2 record, read by AnyReader.
    metadata = yaml.safe_load(open_run(path).metadata['rosbag2']['serialized_metadata'])
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': metadata}))
    os.symlink(os.path.abspath(path), bag / metadata['relative_file_paths'][0])
    with AnyReader([Path(bag)]) as reader:
        decoded = {}
        for connection, _, data in reader.messages(connections=reader.connections):
            decoded.setdefault(connection.topic, []).append(
                reader.deserialize(data, connection.msgtype))
    assert {topic: len(v) for topic, v in decoded.items()} == {t: len(v) for t, v in ours.items()}
    first = decoded[TF_TOPIC][0].transforms[0]
    assert (first.header.frame_id, first.child_frame_id) == _decoded(ours[TF_TOPIC][0])[0][:2]


def _foxglove_reader():
    """
    A folder with read_run.mjs and its pinned npm packages (None: no node or npm).

    Installed once per package.json into a cache outside the repository
    (``~/.cache/qrm_ros/npm/<hash>``, or under ``QRM_ROS_NPM_CACHE``), shared by concurrent
    runs; nothing is written into the repository.
    """
    if shutil.which('node') is None or shutil.which('npm') is None:
        return None
    with open(os.path.join(FOXGLOVE_READER, 'package.json'), 'rb') as handle:
        key = hashlib.sha256(handle.read()).hexdigest()[:16]
    folder = os.path.join(os.environ.get('QRM_ROS_NPM_CACHE') or os.path.join(
        os.path.expanduser('~'), '.cache', 'qrm_ros', 'npm'), 'reader-' + key)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, '.lock'), 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        for name in ('package.json', 'read_run.mjs'):
            shutil.copyfile(os.path.join(FOXGLOVE_READER, name), os.path.join(folder, name))
        if not os.path.exists(os.path.join(folder, 'installed')):
            done = subprocess.run(['npm', 'install', '--no-audit', '--no-fund',
                                   '--loglevel=error'], cwd=folder, capture_output=True,
                                  text=True, timeout=300)
            assert done.returncode == 0, f'npm install failed: {done.stderr[-2000:]}'
            with open(os.path.join(folder, 'installed'), 'w') as handle:
                handle.write(key + '\n')
    return folder


def test_foxglove_reads_it(with_machine):
    folder = _foxglove_reader()
    if folder is None:
        pytest.skip('node and npm are not installed')
    path, geometry = with_machine
    done = subprocess.run(['node', 'read_run.mjs', path], cwd=folder, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    read = json.loads(done.stdout)
    run = open_run(path)
    assert read['profile'] == 'ros2'
    for topic, schema_name in run.topics().items():
        assert read['channels'][topic] == {'messageEncoding': 'cdr', 'schemaName': schema_name,
                                           'schemaEncoding': 'ros2msg'}
        assert len(read['messages'][topic]) == run.message_count(topic), topic
    (description,) = read['messages'][ROBOT_DESCRIPTION_TOPIC]
    assert description['message']['data'] == urdf_text(geometry)
    for message, ours in zip(read['messages'][TF_TOPIC], run.messages([TF_TOPIC])):
        assert int(message['logTime']) == ours.log_time
        assert [(t['header']['frame_id'], t['child_frame_id'],
                 tuple(t['transform']['translation'][k] for k in 'xyz'),
                 tuple(t['transform']['rotation'][k] for k in 'xyzw'),
                 t['header']['stamp']['sec'] * 1_000_000_000 + t['header']['stamp']['nanosec'])
                for t in message['message']['transforms']] == _decoded(ours.data)
    for message, ours in zip(read['messages']['/' + JOINT_STATES_TOPIC],
                             run.messages([JOINT_STATES_TOPIC])):
        decoded = STORE.deserialize_cdr(ours.data, JOINT_STATE_TYPE)
        assert message['message']['name'] == list(decoded.name)
        assert message['message']['position'] == list(decoded.position)


def test_joint_states_waiting_for_the_geometry_are_bounded(tmp_path, monkeypatch):
    from qrm_ros.recording import machine_channels
    monkeypatch.setattr(machine_channels, 'MAX_WAITING_JOINT_STATES', 5)
    geometry = GEOMETRIES['paper']
    run_file = McapRunFile(str(tmp_path / 'run.mcap'), COMPRESSIONS['none'], 1_000_000_000)
    machine = MachineChannels(run_file)
    values = _published(geometry, 0.0, 1.0)
    states = [_joint_state(1000 + i, JOINT_NAMES, [values[n] for n in JOINT_NAMES])
              for i in range(8)]
    for i, data in enumerate(states[:7]):
        machine.joint_state(2000 + i, 1000 + i, data)
    assert not machine.started and machine.dropped == 2
    machine.start(geometry, 9999)
    machine.joint_state(2007, 1007, states[7])
    machine.joint_state(2008, 1008, b'\x00')  # undecodable: no transforms, counted
    run_file.finish()
    assert machine.started and machine.dropped == 3
    run = open_run(str(tmp_path / 'run.mcap'))
    assert [m.log_time for m in run.messages([TF_TOPIC])] == [2002, 2003, 2004, 2005, 2006,
                                                              2007]
    assert [m.log_time for m in run.messages([ROBOT_DESCRIPTION_TOPIC])] == [2002]
    (static,) = run.messages([TF_STATIC_TOPIC])
    assert {stamp for *_, stamp in _decoded(static.data)} == {1002}
