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
Replay of the golden logs in test/data (recorded by the real node and recorder).

Each log is re-derived from its own content:
(a) from the logged input angle, input speed, offset and offset rate at every stamp, the
    kinematics core reproduces the logged flywheel, lever and ram states (and the twist) to
    1e-12;
(b) stepping the node's stepper (ShaperStepper, or MotorStepper for a drive parameter of
    motor) from the first logged sample through the logged parameter changes
    (/parameter_events, stamped by the node's clock between two ticks) at the logged stamps
    reproduces every logged joint position and velocity (and effort, where logged) bit for bit.
    A MotorStepper's state is more than the logged one (its solver's step history), so a
    motor log starts at a reset: the first logged sample is where the node's integration
    started (make_golden_logs.py pauses and resets the node before recording);
(c) a motor log's efforts are the dynamics' at the logged state with the parameters in force
    (metadata, then /parameter_events: a load change mid-run included), at every sample;
    its input torque is the motor law at the logged speed.
And the offline analysis of each speed-drive log finds exactly the commanded settings and
measures TR and SR within the stroke finder's bound of the closed form; of a motor log, it
finds each held setting (the motor's speed reference, the load change) and measures the
efforts of each, once settled, within the sampling bounds of the motor's steady theory.
A change to the physics, the stepping or the analysis that alters their output fails here.
"""

import glob
import json
import math
import os

import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores

from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_drive
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import segments
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.recording.bag_reader import open_run
from qrm_ros.core.motor.motor_stepper import MotorStepper
from qrm_ros.core.measurement.sampling_bounds import BOUNDED_FIGURES
from qrm_ros.core.common.names import JOINT_NAMES, PUBLISHED_JOINT_NAMES
from qrm_ros.core.dynamics.stroke_efforts import lever_radius_coefficient
from qrm_ros.node.shaper_sim.shaper_parameters import MOTOR_PREFIX
from qrm_ros.core.stepping.stepping import ShaperStepper, wrap_angle
from qrm_ros.testing import OTHER_MACHINE_RELATIVE, reference_math
from repo_paths import TEST_DATA

pytestmark = pytest.mark.bits

DATA = TEST_DATA
LOGS = sorted(glob.glob(os.path.join(DATA, '*.mcap')))
JOINTS = list(JOINT_NAMES)
PUBLISHED = list(PUBLISHED_JOINT_NAMES)
# The settings make_golden_logs.py commanded: (offset m, input speed rad/s) per log.
COMMANDED = {
    'steady_positive_offset': [(0.010, 2 * math.pi)],
    'steady_negative_offset': [(-0.010, 2 * math.pi)],
    'offset_and_speed_change': [(0.0, 2 * math.pi), (0.012, 2 * math.pi), (0.012, 9.0),
                                (-0.008, 2 * math.pi)],
}
# The motor-drive logs: what each recorded mid-run, in order (parameter, value).
MOTOR_CHANGES = {
    'motor_cutting_load': [('input_speed', 9.0), ('coupling_offset', -0.008),
                           ('cutting_force', 800.0)],
}
STORE = get_typestore(Stores.ROS2_JAZZY)

# rcl_interfaces/msg/ParameterType -> the ParameterValue field holding it (scalars only).
VALUE_FIELDS = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value'}


def _ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class Log:
    def __init__(self, path):
        run = open_run(path)
        assert not run.truncated
        self.geometry = kin.Geometry(**{k: float(v) for k, v in
                                        run.metadata['qrm_ros.geometry'].items()})
        self.parameters = {k: json.loads(v) for k, v in
                           run.metadata['qrm_ros.parameters'].items()}
        stamps, positions, velocities, efforts, twists, self.events = [], [], [], [], {}, []
        for recorded in run.messages():
            message = STORE.deserialize_cdr(recorded.data, recorded.schema_name)
            topic = recorded.topic
            if topic == '/joint_states':
                # Logs made before the stroke adjustment have the five JOINT_NAMES only.
                assert list(message.name) in (JOINTS, PUBLISHED)
                stamps.append(_ns(message.header.stamp))
                positions.append(message.position)
                velocities.append(message.velocity)
                efforts.append(message.effort)
            elif topic == '/ram/twist':
                twists[_ns(message.header.stamp)] = message.twist.linear.x
            elif topic == '/parameter_events' and message.node == '/shaper_sim':
                for parameter in message.changed_parameters:
                    value = getattr(parameter.value, VALUE_FIELDS[parameter.value.type])
                    self.events.append((_ns(message.stamp), parameter.name, value))
        order = np.argsort(stamps, kind='stable')
        self.stamps = [stamps[i] for i in order]
        joints = len(JOINTS)
        self.position = np.array(positions)[order][:, :joints]
        self.velocity = np.array(velocities)[order][:, :joints]
        self.effort = np.array(efforts)[order][:, :joints]  # (n, 0) when none published
        # The crank radius's joint (m, m/s, N), where logged: (n, 3), else (n, 0).
        self.crank_radius = np.array([np.array(column)[order][:, joints:].ravel()
                                      for column in (positions, velocities, efforts)]).T
        self.motor = self.parameters.get('drive') == 'motor'
        self.twists = twists
        self.events.sort()


@pytest.fixture(scope='module', params=LOGS, ids=lambda p: os.path.basename(p)[:-5])
def log(request):
    return Log(request.param)


MOTOR_LOGS = [path for path in LOGS if os.path.basename(path)[:-5] in MOTOR_CHANGES]


@pytest.fixture(scope='module', params=MOTOR_LOGS, ids=lambda p: os.path.basename(p)[:-5])
def motor_log(request):
    return Log(request.param)


def test_the_golden_logs_are_there_and_small():
    assert {os.path.basename(p)[:-5] for p in LOGS} == set(COMMANDED) | set(MOTOR_CHANGES)
    for path in LOGS:
        assert os.path.getsize(path) <= 1_000_000


def test_core_reproduces_every_logged_state(log):
    angle, offset = log.position[:, 0], log.position[:, 4]
    speed, offset_rate = log.velocity[:, 0], log.velocity[:, 4]
    state = kin.state(log.geometry, offset, angle, speed, 0.0, offset_rate)
    wrapped = np.angle(np.exp(1j * (state.flywheel_angle - log.position[:, 1])))
    assert np.max(np.abs(wrapped)) < 1e-12
    np.testing.assert_allclose(state.flywheel_speed, log.velocity[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.lever_angle, log.position[:, 2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.lever_speed, log.velocity[:, 2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.ram_position, log.position[:, 3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.ram_velocity, log.velocity[:, 3], rtol=0, atol=1e-12)
    matched = [(log.twists[s], v) for s, v in zip(log.stamps, log.velocity[:, 3])
               if s in log.twists]
    assert len(matched) >= len(log.stamps) - 2
    assert all(twist == joint for twist, joint in matched)


def _dynamics(parameters):
    """The mass properties, loads and motor as the node makes them from its parameters."""
    return (dyn.MassProperties(**{n: parameters[n] for n in dyn.MassProperties.field_names()}),
            dyn.Loads(**{n: parameters[n] for n in dyn.Loads.field_names()}),
            dyn.MotorDrive(**{n: parameters[MOTOR_PREFIX + n]
                              for n in dyn.MotorDrive.field_names()}))


DYNAMICS_PARAMETERS = (set(dyn.MassProperties.field_names()) | set(dyn.Loads.field_names())
                       | {MOTOR_PREFIX + n for n in dyn.MotorDrive.field_names()})


def _apply(stepper, parameters, name, value):
    """Do what shaper_sim does on a parameter change (its stepper calls)."""
    parameters[name] = value
    if name == 'input_speed':
        stepper.set_speed_command(value)
    elif name == 'coupling_offset':
        stepper.set_offset_command(value)
    elif name == 'input_acceleration_limit':
        stepper.set_limits(input_acceleration_limit=value)
    elif name == 'offset_rate_limit':
        stepper.set_limits(offset_rate_limit=value)
    elif name in DYNAMICS_PARAMETERS and isinstance(stepper, MotorStepper):
        stepper.set_dynamics(*_dynamics(parameters))
    else:
        assert name in DYNAMICS_PARAMETERS, f'a change of {name} the replay does not know'


def _published(log, stepper, parameters):
    """
    Positions, velocities and efforts as shaper_sim publishes them at the present stamp.

    And the motor drive's stroke screw force: the lever torque's share (shaper_sim).
    """
    sample = stepper.mechanism_state()
    positions = (stepper.input_angle, wrap_angle(sample.flywheel_angle), sample.lever_angle,
                 sample.ram_position, stepper.offset)
    velocities = (stepper.input_speed, sample.flywheel_speed, sample.lever_speed,
                  sample.ram_velocity, stepper.offset_rate)
    screw = None
    if not log.effort.shape[1]:
        efforts = ()  # logged before the node published efforts
    elif isinstance(stepper, MotorStepper):
        efforts = tuple(stepper.efforts())
        screw = efforts[2] * lever_radius_coefficient(log.geometry, sample.flywheel_angle)
    else:
        mass, loads, _ = _dynamics(parameters)
        efforts = tuple(dyn.efforts(
            log.geometry, mass, stepper.offset, stepper.input_angle, stepper.input_speed,
            stepper.input_acceleration, stepper.offset_rate, 0.0,
            dyn.ram_load_force(loads, sample.ram_position, sample.ram_velocity,
                               log.geometry.ram_stroke)))
    return positions, velocities, efforts, screw


def replay(log):
    """
    Step the node's stepper through the log: (index, positions, velocities, efforts, screw).

    The commands in force at the first sample are the metadata's start-up values and any
    change stamped before it; the first sample is taken as the state there.
    """
    parameters = dict(log.parameters)
    events = list(log.events)
    while events and events[0][0] <= log.stamps[0]:  # commands in force at the first sample
        _, name, value = events.pop(0)
        parameters[name] = value
    arguments = (parameters['input_speed'], parameters['coupling_offset'],
                 parameters['input_acceleration_limit'], parameters['offset_rate_limit'])
    if parameters.get('drive') == 'motor':
        stepper = MotorStepper(log.geometry, *_dynamics(parameters), *arguments)
    else:
        stepper = ShaperStepper(log.geometry, *arguments)
    stepper.restore(log.stamps[0], log.position[0, 0], log.velocity[0, 0], log.position[0, 4])
    stepper.set_speed_command(parameters['input_speed'])
    stepper.set_offset_command(parameters['coupling_offset'])
    yield (0, *_published(log, stepper, parameters))
    for k in range(1, len(log.stamps)):
        # A command stamped between two ticks took effect from the earlier tick.
        while events and events[0][0] < log.stamps[k]:
            _, name, value = events.pop(0)
            _apply(stepper, parameters, name, value)
        stepper.integrate_to(log.stamps[k])
        yield (k, *_published(log, stepper, parameters))
    assert not events or events[0][0] >= log.stamps[-1]


def _same(got, logged, scale):
    """Equal: bit for bit where promised, else within OTHER_MACHINE_RELATIVE of each scale."""
    if scale is None:
        return got == logged
    return all(abs(a - b) <= OTHER_MACHINE_RELATIVE * s for a, b, s in zip(got, logged, scale))


def test_stepper_replays_the_logged_trajectory_bit_for_bit(log):
    # The stepper's own state (input angle and speed, offset and its rate) in every log; every
    # joint and effort in the motor logs. The speed-drive logs' derived joints were computed
    # by an earlier core, to within an ulp of today's (test_core_reproduces_...). The speed
    # drive's stepper calls no C library function: bit for bit everywhere; the motor's
    # integration does (its sines): bit for bit on the reference machines.
    stepped = (slice(None), slice(None)) if log.motor else ([0, 4], [0, 4])
    scales = (None, None, None) if reference_math() or not log.motor else tuple(
        np.max(np.abs(values), axis=0).tolist() for values in (
            log.position, log.velocity, log.effort))
    for k, positions, velocities, efforts, screw in replay(log):
        if k == 0 and not log.motor:
            continue  # the state restored
        got = (np.array(positions)[stepped[0]].tolist(),
               np.array(velocities)[stepped[1]].tolist())
        logged = (log.position[k][stepped[0]].tolist(), log.velocity[k][stepped[1]].tolist())
        assert _same(got[0], logged[0], scales[0]) and _same(got[1], logged[1], scales[1]), (
            f'sample {k} at {log.stamps[k]} ns: replay {got} != log {logged}')
        if log.motor:
            assert _same(list(efforts), log.effort[k].tolist(), scales[2]), (
                f'sample {k} at {log.stamps[k]} ns: efforts {efforts} != log {log.effort[k]}')
        if log.crank_radius.size:
            # No stroke change in the logs: the radius stands still.
            assert log.crank_radius[k, :2].tolist() == [log.geometry.crank_radius, 0.0]
        if log.motor and log.crank_radius.size:
            assert _same([screw], [log.crank_radius[k, 2]], None if scales[2] is None else [
                max(scales[2])]), f'sample {k} at {log.stamps[k]} ns: screw'


def test_the_motor_logs_start_at_a_reset_and_hold_the_changes(log, request):
    name = os.path.basename(request.node.callspec.params['log'])[:-5]
    if not log.motor:
        assert not any(name in DYNAMICS_PARAMETERS for _, name, _ in log.events)
        return
    # The node's integration starts here: input angle 0 at the commanded speed and offset.
    assert log.position[0, 0] == 0.0
    assert log.velocity[0, 0] == log.parameters['input_speed']
    assert log.position[0, 4] == log.parameters['coupling_offset']
    assert [(n, v) for _, n, v in log.events] == MOTOR_CHANGES[name]
    assert all(log.stamps[0] < stamp < log.stamps[-1] for stamp, _, _ in log.events)


def _in_force(log):
    """Yield (index, parameters in force) per sample: a change counts from the next sample."""
    parameters, events = dict(log.parameters), list(log.events)
    for k, stamp in enumerate(log.stamps):
        while events and events[0][0] < stamp:
            _, name, value = events.pop(0)
            parameters[name] = value
        yield k, dict(parameters)


def _dynamics_efforts(log, k, parameters, at=None):
    """
    The efforts the dynamics give at sample k's logged state and input torque.

    The input acceleration is not logged: it is the one the logged input torque gives
    (tau1 = M theta'' + b, dynamics.md); the other four efforts then follow from the chain.
    The ram load is the one at sample `at`'s logged ram position and velocity (default k).
    """
    mass, loads, _ = _dynamics(parameters)
    geometry, at = log.geometry, k if at is None else at
    load = dyn.ram_load_force(loads, float(log.position[at, 3]), float(log.velocity[at, 3]),
                              geometry.ram_stroke)
    angle, offset = log.position[k, 0], log.position[k, 4]
    speed, offset_rate = log.velocity[k, 0], log.velocity[k, 4]
    bias = dyn.efforts(geometry, mass, offset, angle, speed, 0.0, offset_rate, 0.0,
                       load).input_torque
    inertia = dyn.generalized_inertia(geometry, mass, offset, angle)
    acceleration = (log.effort[k, 0] - bias) / inertia
    return np.array(dyn.efforts(geometry, mass, offset, angle, speed, acceleration,
                                offset_rate, 0.0, load))


def _agree(expected, logged):
    """Equal to roundoff: 1e-9 of the input torque's size (N m), ten times that in N."""
    scale = np.array([1.0, 1.0, 1.0, 10.0, 10.0]) * max(1.0, abs(logged[0]))
    return bool(np.all(np.abs(expected - logged) <= 1e-9 * scale))


def _disagreeing_samples(log):
    return [k for k, parameters in _in_force(log)
            if not _agree(_dynamics_efforts(log, k, parameters), log.effort[k])]


def test_motor_log_efforts_are_the_dynamics_at_every_sample(motor_log):
    # A stamp just before a load switch (a reversal, a workpiece edge) reads the mode it is
    # in: MotorStepper starts the next segment only once the stamps pass the switch.
    assert _disagreeing_samples(motor_log) == []


def test_motor_log_input_torque_is_the_motor_law(motor_log):
    """
    The logged input torque is clip(k (w_ref - w), +-T_max) at the logged input speed.

    w_ref is the commanded speed ramped at input_acceleration_limit from the tick before
    each command; the log holds reversals and the tool entering and leaving the workpiece
    in every stroke pair.
    """
    log = motor_log
    reference = ramp_start = None
    reversals = edges = 0
    for k, parameters in _in_force(log):
        motor = _dynamics(parameters)[2]
        command, limit = parameters['input_speed'], parameters['input_acceleration_limit']
        if reference is None or command != reference[1]:
            start = log.stamps[max(k - 1, 0)]
            begin = (log.velocity[0, 0] if reference is None
                     else _ramp_value(reference, ramp_start, start, limit))
            reference, ramp_start = (begin, command), start
        speed_reference = _ramp_value(reference, ramp_start, log.stamps[k], limit)
        law = min(max(motor.speed_stiffness * (speed_reference - log.velocity[k, 0]),
                      -motor.max_torque), motor.max_torque)
        assert log.effort[k, 0] == pytest.approx(law, rel=0, abs=1e-8), k
        if k:
            reversals += np.sign(log.velocity[k, 3]) != np.sign(log.velocity[k - 1, 3])
            inside = [abs(log.position[i, 3]) <= 0.5 * parameters['cutting_length']
                      for i in (k - 1, k)]
            edges += log.velocity[k, 3] < 0 and inside[0] != inside[1]
    pairs = (log.stamps[-1] - log.stamps[0]) / 1e9 / (2 * math.pi / 9.0)  # at most
    assert reversals >= pairs and edges >= pairs, (reversals, edges)


def _ramp_value(reference, start_ns, stamp_ns, acceleration_limit):
    """The value at stamp_ns of a ramp from reference[0] to reference[1] begun at start_ns."""
    begin, end = reference
    step = acceleration_limit * (stamp_ns - start_ns) / 1e9
    return end if step >= abs(end - begin) else begin + math.copysign(step, end - begin)


def test_a_load_change_mid_run_is_recoverable_from_the_file(motor_log):
    """
    The metadata holds the start-up values; /parameter_events holds each change after.

    After the logged cutting_force change, the logged efforts are the dynamics' with the
    changed value (test_motor_log_efforts_...), and not with the metadata's; the replay with
    it is bit for bit (test_stepper_...), without it the motion parts at the next cut: the
    file's parameter events are needed to explain the run, and they suffice.
    """
    log = motor_log
    stamp, name, value = next(event for event in log.events if event[1] == 'cutting_force')
    assert value != log.parameters[name]
    after = [k for k, stamp_ns in enumerate(log.stamps) if stamp_ns > stamp]
    in_force = dict(_in_force(log))
    start_up = dict(log.parameters, **{n: v for _, n, v in log.events if n != name})
    cutting = [k for k in after if log.velocity[k, 3] < 0.0
               and abs(log.position[k, 3]) < 0.5 * in_force[k]['cutting_length']]
    assert len(cutting) >= 20
    for k in cutting:
        assert in_force[k][name] == value
        assert not _agree(_dynamics_efforts(log, k, start_up), log.effort[k]), k
    # And the node's motion: replayed with the start-up value, it leaves the log at the
    # first cut after the change.
    unchanged = Log.__new__(Log)
    unchanged.__dict__.update(vars(log), events=[(s, n, log.parameters[n] if n == name else v)
                                                 for s, n, v in log.events])
    speed_scale = None if reference_math() else [float(np.max(np.abs(log.velocity[:, 0])))]
    first = next(k for k, _, velocities, _, _ in replay(unchanged)
                 if not _same([velocities[0]], [log.velocity[k, 0]], speed_scale))
    assert first == next(k for k in after if log.velocity[k, 3] < 0.0
                         and abs(log.position[k, 3]) <= 0.5 * in_force[k]['cutting_length'])


@pytest.mark.parametrize('name', sorted(COMMANDED))
def test_analysis_finds_the_commanded_settings_and_theory(name):
    path = os.path.join(DATA, name + '.mcap')
    result = measurement.analyse(recorded_run.read_recording(path))
    assert [(row['offset'], row['input_speed']) for row in result.rows] == COMMANDED[name]
    for row in result.rows:
        assert row['stroke_pairs'] >= 2
        tolerance = (abs(row['input_speed']) * 0.01) ** 3  # derived in test_strokes
        for key in ('time_ratio', 'speed_ratio', 'peak_speed_ratio'):
            assert abs(row[f'{key}_relative_error']) < tolerance, (key, row)
        assert row['time_ratio_theory'] == pytest.approx(
            kin.time_ratio_rk4(result.recording.geometry, row['offset']), rel=1e-9)
        # The sampling bounds (added to the rows later): each covers its figure's error
        # and, at 100 Hz, supports it to 1e-3.
        for key in BOUNDED_FIGURES:
            bound, theory = row[f'{key}_sampling_bound'], row[f'{key}_theory']
            assert bound < 1e-3 * abs(theory), (key, row)
            assert abs(row[f'{key}_measured'] - theory) <= bound + 1e-9 * abs(theory), (key, row)


def test_analysis_reads_a_motor_logs_drive_as_started(motor_log, request):
    """The analysis takes the drive, masses and loads from the metadata: the start-up values."""
    path = request.node.callspec.params['motor_log']
    drive = recorded_run.read_recording(path).drive
    mass, loads, motor = _dynamics(motor_log.parameters)
    assert [part.as_dict() for part in drive] == [part.as_dict() for part in (mass, loads, motor)]


def _steady_spans(log, samples):
    """
    The spans a motor log's settings were held: each change to the next, once settled.

    A span starts once the speed reference's ramp has ended and the offset is at rest at its
    command (its rate's jump there is an impulse), and the motor's transient has decayed:
    the speed error decays as exp(-t k / M) (dynamics.md, T_m = k (w_ref - w)), so
    30 M_max / k after the last of these leaves e^-30 of it (M_max: the largest generalised
    inertia the span's samples see).
    """
    in_force = [parameters for _, parameters in _in_force(log)]
    changes = [0] + [k for k in range(1, len(in_force)) if in_force[k] != in_force[k - 1]]
    for start, end in zip(changes, changes[1:] + [len(in_force)]):
        parameters = in_force[start]
        mass, loads, motor = _dynamics(parameters)
        inertia = np.max(dyn.generalized_inertia(log.geometry, mass, samples.offset[start:end],
                                                 samples.input_angle[start:end]))
        ramp = abs(parameters['input_speed'] - samples.input_speed[max(start - 1, 0)]) / (
            parameters['input_acceleration_limit'])
        at_rest = [k for k in range(start, end) if samples.offset_rate[k] == 0.0
                   and samples.offset[k] == parameters['coupling_offset']]
        assert at_rest == list(range(at_rest[0], end))  # the offset stays once there
        settled = (max(samples.time[start] + ramp, samples.time[at_rest[0]])
                   + 30.0 * inertia / motor.speed_stiffness)
        held = [k for k in at_rest if samples.time[k] >= settled]
        yield (segments.Segment(held[0], held[-1] + 1, parameters['coupling_offset'],
                                parameters['input_speed']),
               recorded_drive.Drive(mass, loads, motor))


def _motor_bounds(geometry, samples, segment, row, loads):
    """
    What sampling may cost each figure, measured (the log's dt) and theory (T / 400).

    test_analysis_efforts derives these for a constant speed; under the motor the speed
    swings by Cs about its mean, below the command, so the ram's peak speed is at most
    (1 + Cs) that at the commanded speed. speed_fluctuation's theory samples each revolution
    400 times and integrates by the trapezoid rule too, so it errs the same way at its step.
    Peaks: each misses at most the largest change between neighbouring samples (the
    theory's finer sampling less). Cs: each extreme likewise, over the mean speed.
    """
    span = slice(segment.start, segment.end)
    speed = abs(row['input_speed'])
    period = 2 * math.pi / speed
    swing = 1.0 + row['speed_fluctuation_theory']
    peak_cut = kin.peak_ram_speeds(geometry, row['offset'], speed)[0] * swing
    rms, peak = row['rms_input_torque_theory'], row['peak_input_torque_theory']
    jump = loads.cutting_force * peak_cut / speed  # the torque's jump at an edge, N m

    def energy(step):
        return loads.cutting_force * peak_cut * step + rms * 2 * math.pi * (speed * step) ** 2

    def rms_error(step):
        return (2 * jump * peak * step / period) / (2 * rms) + rms * (speed * step) ** 2

    steps = (float(np.max(np.diff(samples.time[span]))), period / 400)
    largest_change = {
        name: 2 * float(np.max(np.abs(np.diff(values[span]))))
        for name, values in (('peak_input_torque', samples.input_torque),
                             ('peak_offset_force', samples.offset_force))}
    mean_speed = 2 * math.pi / period / swing
    return {
        **largest_change,
        'energy_per_pair': sum(map(energy, steps)),
        'mean_input_power': sum(map(energy, steps)) / period,
        'rms_input_torque': sum(map(rms_error, steps)),
        'speed_fluctuation': 2 * float(np.max(np.abs(np.diff(samples.input_speed[span]))))
        / mean_speed,
    }


def test_analysis_measures_a_motor_logs_efforts_within_sampling(motor_log, request):
    """
    qrm_analyze's measurement of each held setting: the motor's steady theory, to sampling.

    The settled spans are given here (qrm_analyze's own segments start at the ramp's end,
    settling included: the test below); each is
    measured by measurement.measure_segment with the drive in force there (the load change
    included), against steady_running.speed_fluctuation's steady state.
    """
    path = request.node.callspec.params['motor_log']
    recording = recorded_run.read_recording(path)
    samples = recording.samples
    rows = 0
    for segment, drive in _steady_spans(motor_log, samples):
        row = measurement.measure_segment(samples, segment, recording.geometry, drive)
        assert row['stroke_pairs'] >= 2 and row['stroke_pairs_with_efforts'] >= 2
        bounds = _motor_bounds(recording.geometry, samples, segment, row, drive.loads)
        for name, bound in bounds.items():
            error = row[f'{name}_measured'] - row[f'{name}_theory']
            assert abs(error) <= bound, (row['offset'], row['input_speed'], name, error, bound)
        rows += 1
    assert rows == len(motor_log.events) + 1


def test_analysis_finds_a_motor_logs_commanded_settings(request, motor_log):
    # One segment per held setting: the offset, the speed reference (recovered from each
    # sample's speed and torque, to round-off) and the loads (the 800 N change splits one).
    path = request.node.callspec.params['motor_log']
    result = measurement.analyse(recorded_run.read_recording(path))
    settings = [(motor_log.parameters['coupling_offset'], motor_log.parameters['input_speed'])]
    for _, name, value in motor_log.events:
        offset, speed = settings[-1]
        settings.append((value, speed) if name == 'coupling_offset' else
                        (offset, value) if name == 'input_speed' else (offset, speed))
    assert [row['offset'] for row in result.rows] == [offset for offset, _ in settings]
    assert [row['input_speed'] for row in result.rows] == [
        pytest.approx(speed, rel=1e-13) for _, speed in settings]
    assert [t['change'] for t in result.transitions][-1] == 'cutting_force 400.0 -> 800.0'
    for row in result.rows:
        assert row['stroke_pairs'] >= 2
        for key in ('energy_per_pair', 'rms_input_torque', 'speed_fluctuation'):
            assert abs(row[f'{key}_relative_error']) < 1e-2, (key, row)
