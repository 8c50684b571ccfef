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
qrm_analyze's effort figures, against the drive's exact theory (speed_drive, steady_running).

The recorded efforts are exact at their stamps (the node's, or the core's in synthetic runs),
so a measured figure differs from theory only by what sampling loses. The bounds, for a
steady segment sampled every dt at input speed w:

* peak |input torque| and |offset force|: the true peak lies within one sample step of a
  sample, so the largest change between neighbouring samples bounds what is missed;
* energy per pair (and mean power): the torque jumps at the workpiece's two edges by
  F_c |dx/d(theta)| <= F_c v_peak / w (v_peak: the peak cutting speed); the trapezoid rule
  over the interval holding a jump errs by at most jump x w dt / 2, so both edges cost at
  most F_c v_peak dt; friction flips where dx/d(theta) = 0 (no torque jump); the smooth rest
  costs O((w dt)^2) of the torque's size over the pair's interpolated ends;
* RMS torque: the same jumps in T^2 (<= 2 T_peak x jump each), halved by the square root;
* flywheel speed swing: found on a cubic Hermite interpolant, O((w dt)^3) relative;
* speed fluctuation under the ideal speed drive: exactly 0.
"""

import json
import math
import os
import time

import numpy as np
import pytest

from qrm_ros.analysis import joint_state_decoding
from qrm_ros.analysis import measurement
from qrm_ros.analysis import recorded_drive
from qrm_ros.analysis import recorded_run
from qrm_ros.analysis import report
from qrm_ros.analysis import segments
from qrm_ros.analysis import theory
from qrm_ros.analysis import figures
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.measurement.effort_theory import EFFORT_FIGURES, ZERO_CAN_BE_EXACT
from qrm_ros.core.motor.motor_stepper import simulate
from qrm_ros.core.dynamics.speed_drive import pair_efforts
from synthetic_run import write_run
from repo_paths import TEST_DATA

PAPER = kin.Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()
DATA = TEST_DATA
# The golden logs recorded before the node published efforts (motor_cutting_load has them).
GOLDEN = ['offset_and_speed_change.mcap', 'steady_negative_offset.mcap',
          'steady_positive_offset.mcap']


def sampling_bounds(samples, segment, row, loads):
    """The bounds of the module docstring for one analysed segment (absolute values)."""
    span = slice(segment.start, segment.end)
    step = float(np.max(np.diff(samples.time[span])))
    speed = abs(row['input_speed'])
    angle_step = speed * step
    torque = samples.input_torque[span]
    peak_cut, _ = kin.peak_ram_speeds(PAPER, row['offset'], row['input_speed'])
    edges = loads.cutting_force * peak_cut * step  # J, both workpiece edges
    smooth = row['rms_input_torque_theory'] * 2 * math.pi * angle_step ** 2
    period = 2 * math.pi / speed
    jump = loads.cutting_force * peak_cut / speed
    mean_square = (2 * jump * row['peak_input_torque_theory'] * step) / period
    return {
        'peak_input_torque': float(np.max(np.abs(np.diff(torque)))),
        'peak_offset_force': float(np.max(np.abs(np.diff(samples.offset_force[span])))),
        'energy_per_pair': edges + smooth,
        'mean_input_power': (edges + smooth) / period,
        'rms_input_torque': mean_square / (2 * row['rms_input_torque_theory'])
        + row['rms_input_torque_theory'] * angle_step ** 2,
        'flywheel_speed_swing': row['flywheel_speed_swing_theory'] * angle_step ** 3,
    }


def check_against_theory(result, loads, mass=MASS):
    samples = result.recording.samples
    for row, segment in zip(result.rows, result.segments):
        assert row['stroke_pairs'] >= 1
        assert row['stroke_pairs_with_efforts'] == row['stroke_pairs']
        exact = pair_efforts(PAPER, mass, loads, row['offset'], row['input_speed'])
        for name in EFFORT_FIGURES:
            expected = getattr(exact, name)
            if row[f'{name}_theory'] == 0.0:  # no loads: zero up to roundoff
                assert abs(expected) < 1e-9 * row['rms_input_torque_theory']
            else:
                assert row[f'{name}_theory'] == expected
        bounds = sampling_bounds(samples, segment, row, loads)
        for name, bound in bounds.items():
            error = row[f'{name}_measured'] - row[f'{name}_theory']
            assert abs(error) <= bound, (row['offset'], name, error, bound)
            if row[f'{name}_theory'] != 0.0:
                assert row[f'{name}_relative_error'] == pytest.approx(
                    row[f'{name}_measured'] / row[f'{name}_theory'] - 1.0, rel=1e-12)
        assert row['speed_fluctuation_theory'] == 0.0
        assert row['speed_fluctuation_measured'] == 0.0
        assert row['speed_fluctuation_absolute_error'] == 0.0
        assert row['speed_fluctuation_relative_error'] is None


@pytest.fixture(scope='module')
def synthetic(tmp_path_factory):
    """Three offsets at 500 Hz with the small shaper's masses and loads (core efforts)."""
    path = tmp_path_factory.mktemp('efforts') / 'run.mcap'
    write_run(path, PAPER, [-0.012, 0.0, 0.015], hold=2.3, rate=500.0, mass=MASS, loads=LOADS)
    return measurement.analyse(recorded_run.read_recording(str(path)))


def test_recorded_parameters_give_the_theory(synthetic):
    drive = synthetic.recording.drive
    assert drive is not None and drive.motor is None and synthetic.recording.drive_problem is None
    assert drive.mass.as_dict() == MASS.as_dict() and drive.loads.as_dict() == LOADS.as_dict()


def test_measured_efforts_match_theory_within_the_sampling_bounds(synthetic):
    assert [row['offset'] for row in synthetic.rows] == [-0.012, 0.0, 0.015]
    check_against_theory(synthetic, LOADS)


def test_energy_per_pair_is_the_loads_work(synthetic):
    work = LOADS.cutting_force * LOADS.cutting_length + 2 * LOADS.ram_friction * PAPER.ram_stroke
    for row in synthetic.rows:
        assert row['energy_per_pair_theory'] == pytest.approx(work, rel=1e-12)
        assert row['mean_input_power_theory'] == pytest.approx(work * row['input_speed']
                                                               / (2 * math.pi), rel=1e-12)


def test_flywheel_speed_swing_is_eq4s_extremes():
    """The closed form against eq. 4 sampled densely (the extremes are at sin(theta) = -+1)."""
    theta = np.linspace(0.0, 2 * math.pi, 200_001)
    for offset in (-0.02, -0.005, 0.0, 0.0111, 0.02):
        speed = kin.state(PAPER, offset, theta, 1.0).flywheel_speed
        assert theory.flywheel_speed_swing(PAPER, offset) == pytest.approx(
            speed.max() / speed.min(), rel=1e-12)


def test_input_torque_parts_add_up_and_mean_what_they_say():
    drive = recorded_drive.Drive(MASS, LOADS, None)
    theta = np.linspace(0.0, 2 * math.pi, 3001)
    speed, offset = 5.0, 0.01
    parts = theory.input_torque_parts(PAPER, drive, offset, theta, speed)
    motion = kin.state(PAPER, offset, theta, speed)
    load = dyn.ram_load_force(LOADS, motion.ram_position, motion.ram_velocity, PAPER.ram_stroke)
    total = dyn.efforts(PAPER, MASS, offset, theta, speed, external_ram_force=load).input_torque
    np.testing.assert_allclose(parts.total, total, rtol=0, atol=1e-12 * np.max(np.abs(total)))
    np.testing.assert_allclose(parts.inertia + parts.cutting + parts.gravity_and_friction,
                               parts.total, rtol=0, atol=1e-12 * np.max(np.abs(total)))
    # Inertia: the kinetic energy's rate, dT/dt = T_inertia x w, so it sums to 0 over a turn.
    assert abs(np.trapezoid(parts.inertia, theta)) < 1e-6 * np.max(np.abs(parts.inertia))
    # Cutting: F_c x (-dx/d(theta)) while the tool cuts, 0 elsewhere (x' = v / w).
    cutting = (motion.ram_velocity < 0) & (np.abs(motion.ram_position)
                                           <= LOADS.cutting_length / 2)
    np.testing.assert_allclose(parts.cutting, np.where(
        cutting, -LOADS.cutting_force * motion.ram_velocity / speed, 0.0), rtol=1e-9,
        atol=1e-9 * LOADS.cutting_force)


def test_fast_decoding_reads_the_efforts_as_rosbags_does(synthetic, monkeypatch):
    path = synthetic.recording.path
    monkeypatch.setattr(joint_state_decoding, 'FAST_DECODING', False)
    slow = recorded_run.read_recording(path)
    for name, values in slow.samples._asdict().items():
        np.testing.assert_array_equal(getattr(synthetic.recording.samples, name), values,
                                      err_msg=name)
    assert slow.samples.input_torque is not None


def test_effort_keys_in_json_and_csv(synthetic, tmp_path):
    report.write_outputs(synthetic, str(tmp_path / 'r.csv'), str(tmp_path / 'r.json'))
    document = json.loads((tmp_path / 'r.json').read_text())
    header = (tmp_path / 'r.csv').read_text().splitlines()[0].split(',')
    for name in EFFORT_FIGURES + ('speed_fluctuation', 'flywheel_speed_swing'):
        for suffix in ('measured', 'measured_std', 'theory', 'relative_error'):
            assert f'{name}_{suffix}' in header
            assert f'{name}_{suffix}' in document['segments'][0]
    for name in ZERO_CAN_BE_EXACT:
        assert f'{name}_absolute_error' in header


def test_table_shows_the_efforts(synthetic):
    table = report.format_table(synthetic)
    assert 'efforts: theory for the recorded masses and loads, ideal speed drive' in table
    row = synthetic.rows[2]
    assert f'{row["peak_input_torque_theory"]:10.4f}' in table
    assert '(abs.)' in table  # the speed fluctuation's zero theory


def _lines(figure, gid):
    return [line for axes in figure.axes for line in axes.get_lines() if line.get_gid() == gid]


def test_input_torque_figure_plots_the_theory_and_the_recorded_torque(synthetic, tmp_path):
    paths = figures.write_figures(synthetic, str(tmp_path))
    names = {os.path.basename(path) for path in paths}
    assert {'fig_input_torque.png', 'fig_offset_cost.png'} <= names
    figure = figures.input_torque_figure(synthetic)
    drive = synthetic.recording.drive
    for name in figures.TORQUE_PARTS:
        lines = _lines(figure, name)
        assert len(lines) == len(synthetic.rows)
        for line, row in zip(lines, synthetic.rows):
            theta, torque = line.get_data()
            parts = theory.input_torque_parts(PAPER, drive, row['offset'], np.radians(theta),
                                              row['input_speed'])
            np.testing.assert_allclose(torque, getattr(parts, name), rtol=1e-12, atol=1e-9)
    samples = synthetic.recording.samples
    for line in _lines(figure, 'recorded'):
        angle, torque = line.get_data()
        assert np.isin(torque, samples.input_torque).all()  # recorded values, unchanged
        assert angle.min() >= 0.0 and angle.max() <= 360.0


def test_offset_cost_figure_plots_pair_efforts_and_eq4(synthetic):
    figure = figures.offset_cost_figure(synthetic)
    peak, swing = _lines(figure, figures.THEORY)
    x, y = peak.get_data()
    assert x.size == figures.COST_CURVE_POINTS
    for ratio, value in list(zip(x, y))[::5]:
        offset = ratio * PAPER.pivot_distance
        assert value == pytest.approx(pair_efforts(PAPER, MASS, LOADS, offset, 2 * math.pi
                                                   ).peak_input_torque, rel=1e-12)
    x, y = swing.get_data()
    radius = PAPER.coupling_radius
    delta = np.abs(x * PAPER.pivot_distance)
    np.testing.assert_allclose(y, (radius + delta) / (radius - delta), rtol=1e-12)
    measured = [line for line in figure.axes[0].get_lines() if line.get_gid() != figures.THEORY
                and line.get_linestyle() == 'None']
    assert measured, 'the measured peaks are drawn'


@pytest.mark.parametrize('log', GOLDEN)
def test_golden_logs_without_efforts_analyse_as_before(log, tmp_path):
    """Recorded before the node published efforts: kinematics as ever, efforts absent."""
    recording = recorded_run.read_recording(os.path.join(DATA, log))
    assert recording.samples.input_torque is None and recording.samples.offset_force is None
    assert recording.drive is None
    assert 'lacks' in recording.drive_problem and 'cutting_force' in recording.drive_problem
    assert recording.complete
    result = measurement.analyse(recording)
    for row in result.rows:
        assert row['stroke_pairs_with_efforts'] == 0
        for name in EFFORT_FIGURES:
            assert row[f'{name}_measured'] is None and row[f'{name}_theory'] is None
        assert row['speed_fluctuation_measured'] == 0.0  # the speed is recorded
        assert row['flywheel_speed_swing_measured'] == pytest.approx(
            row['flywheel_speed_swing_theory'], rel=(abs(row['input_speed']) * 0.01) ** 3)
    assert 'efforts: not recorded in this file' in report.format_table(result)
    figure = figures.input_torque_figure(result)
    texts = [text.get_text() for axes in figure.axes for text in axes.texts]
    assert texts and all('not recorded' in text for text in texts)
    assert len(figures.write_figures(result, str(tmp_path))) == len(figures.FIGURES)


def test_missing_or_bad_parameters_say_why_there_is_no_theory():
    assert recorded_drive.drive_from_metadata(None, PAPER) == (
        None, 'the file has no qrm_ros.parameters metadata')
    stored = {name: json.dumps(value) for name, value in {**MASS.as_dict(),
                                                          **LOADS.as_dict()}.items()}
    drive, problem = recorded_drive.drive_from_metadata(stored, PAPER)
    assert problem is None and drive.motor is None
    long_cut = dict(stored, cutting_length='0.5')
    assert 'cutting_length = 0.5 m is out of range' in recorded_drive.drive_from_metadata(
        long_cut, PAPER)[1]
    odd = dict(stored, drive='"steam"')
    assert "the recorded drive 'steam' is unknown" in recorded_drive.drive_from_metadata(
        odd, PAPER)[1]
    motor = dict(stored, drive='"motor"', motor_speed_stiffness='360.0')
    assert recorded_drive.drive_from_metadata(motor, PAPER)[1].endswith(
        'lacks motor_max_torque (recorded before the node had them)')
    drive, _ = recorded_drive.drive_from_metadata(dict(motor, motor_max_torque='250.0'), PAPER)
    assert drive.motor.as_dict() == {'speed_stiffness': 360.0, 'max_torque': 250.0}


# A real recording: shaper_sim and mcap_recorder as processes, the loads set at start-up.
REAL_OFFSETS = (-0.010, 0.012)
REAL_SPEED = 2 * math.pi
REAL_RATE = 250.0


@pytest.fixture(scope='module')
def real_run(tmp_path_factory):
    from qrm_ros.cli.qrm_main import RECORDER_SETTLE_TIME, start_child, stop_child
    from qrm_ros.node.main_job.main_job_conductor import Conductor
    folder = tmp_path_factory.mktemp('real_efforts')
    path = str(folder / 'run.mcap')
    env = dict(os.environ)
    loads = [f'{name}:={value!r}' for name, value in LOADS.as_dict().items()]
    sim = start_child('shaper_sim', [item for setting in [
        f'coupling_offset:={REAL_OFFSETS[0]!r}', f'input_speed:={REAL_SPEED!r}',
        f'publish_rate:={REAL_RATE!r}', 'offset_rate_limit:=0.02', *loads]
        for item in ('-p', setting)], str(folder / 'shaper_sim.log'), env)
    recorder, conductor = None, Conductor()
    try:
        conductor.wait_for(conductor.sim_ready, 60.0, 'shaper_sim to start')
        recorder = start_child('mcap_recorder', ['-p', f'output:={path}'],
                               str(folder / 'mcap_recorder.log'), env)
        conductor.wait_for(conductor.recorder_subscribed, 60.0, 'mcap_recorder to subscribe')
        since = time.time() + RECORDER_SETTLE_TIME
        for offset in REAL_OFFSETS:
            conductor.set_parameters(coupling_offset=offset)
            conductor.wait_for(lambda: conductor.steady_pairs_at(offset, since) >= 2, 60.0,
                               f'2 steady pairs at {offset} m')
    finally:
        conductor.close()
        if recorder is not None:
            stop_child(recorder)
        stop_child(sim)
    return measurement.analyse(recorded_run.read_recording(path))


def test_a_real_recording_measures_the_theory(real_run):
    assert real_run.recording.complete
    assert real_run.recording.drive is not None and real_run.recording.drive.motor is None
    assert real_run.recording.drive.loads.as_dict() == LOADS.as_dict()
    rows = [row for row in real_run.rows if row['stroke_pairs'] >= 1]
    assert {row['offset'] for row in rows} == set(REAL_OFFSETS)
    check_against_theory(real_run._replace(
        rows=rows, segments=[s for s, r in zip(real_run.segments, real_run.rows)
                             if r['stroke_pairs'] >= 1]), LOADS)


# Runs of the motor drive: its speed fluctuates, its reference is the setting.
def _motor_samples(simulation, offset=0.01):
    """Samples of a motor simulation (the fields the segmenting reads; the ram's exact)."""
    motion = kin.state(PAPER, offset, simulation.input_angle, simulation.input_speed)
    zeros = np.zeros(simulation.time.shape)
    return recorded_run.Samples(simulation.time, simulation.input_angle, simulation.input_speed,
                                motion.flywheel_angle, motion.flywheel_speed,
                                motion.ram_position, motion.ram_velocity, zeros + offset, zeros,
                                simulation.efforts.input_torque, simulation.efforts.offset_force)


def test_the_motor_speed_reference_is_recovered_from_each_sample():
    motor = dyn.MotorDrive(speed_stiffness=50.0, max_torque=45.0)
    mass = dyn.MassProperties.small_shaper()
    # Starting at 4 rad/s the reference ramps to 2 pi at 4 rad/s^2, then holds.
    simulation = simulate(PAPER, mass, LOADS, motor, 0.01, 2 * math.pi, 3.0, 500.0,
                          initial_speed=4.0, input_acceleration_limit=4.0)
    # The published input torque is the inverse dynamics' at the state: the motor's torque
    # to round-off.
    np.testing.assert_allclose(simulation.efforts.input_torque, simulation.motor_torque,
                               rtol=0.0, atol=1e-12 * motor.max_torque)
    reference = np.minimum(4.0 + 4.0 * simulation.time, 2 * math.pi)
    found = segments.setting_speed(_motor_samples(simulation),
                                   recorded_drive.Drive(mass, LOADS, motor))
    limited = np.abs(simulation.motor_torque) >= motor.max_torque
    assert limited.any() and not limited.all()  # this weak motor is at its limit each turn
    # At the limit a sample does not hold the reference: a span between two samples that
    # agree on it takes theirs; the span the run ends in has only one side, so none.
    last_known = np.flatnonzero(~limited)[-1]
    ends = limited & (np.arange(limited.size) > last_known)
    assert ends.any() and np.all(np.isnan(found[ends]))
    assert np.count_nonzero(limited & ~ends) > 50
    np.testing.assert_allclose(found[~ends], reference[~ends], rtol=1e-13)
    # Under the ideal speed drive the setting is the recorded speed itself.
    samples = _motor_samples(simulation)
    assert segments.setting_speed(samples, recorded_drive.Drive(mass, LOADS, None)) is (
        samples.input_speed)


def _limited_samples(references, limited, motor):
    """Samples whose speed gives these references, at the torque limit where limited."""
    references = np.asarray(references, dtype=float)
    torque = np.where(limited, motor.max_torque, 0.5 * motor.max_torque)
    speed = references - torque / motor.speed_stiffness  # the motor's law, k (ref - speed)
    time = np.arange(references.size) * 0.01
    zeros = np.zeros(references.size)
    return recorded_run.Samples(time, speed * time, speed, zeros, zeros, zeros, zeros, zeros,
                                zeros, torque, zeros)


def test_a_span_at_the_torque_limit_takes_the_reference_both_its_sides_agree_on():
    motor = dyn.MotorDrive(speed_stiffness=50.0, max_torque=45.0)
    drive = recorded_drive.Drive(dyn.MassProperties.small_shaper(), LOADS, motor)
    limited = np.array([False] * 3 + [True] * 3 + [False] * 3)
    same = segments.setting_speed(_limited_samples([2.0] * 9, limited, motor), drive)
    np.testing.assert_allclose(same, 2.0, rtol=1e-15)
    # A command during the span: the two sides disagree, the span has no setting.
    changed = segments.setting_speed(_limited_samples([2.0] * 4 + [3.0] * 5, limited, motor),
                                     drive)
    assert np.all(np.isnan(changed[limited]))
    np.testing.assert_allclose(changed[~limited], [2.0] * 3 + [3.0] * 3, rtol=1e-15)
    # At an end only one side is known: no setting.
    ends = np.array([True] * 2 + [False] * 5 + [True] * 2)
    assert np.all(np.isnan(segments.setting_speed(_limited_samples([2.0] * 9, ends, motor),
                                                  drive)[ends]))


def test_a_motor_at_its_torque_limit_every_revolution_is_one_steady_segment():
    motor = dyn.MotorDrive.small_shaper()
    mass = dyn.MassProperties.small_shaper()
    offset = 0.015  # the peak torque the ideal drive would need is above the motor's limit
    simulation = simulate(PAPER, mass, LOADS, motor, offset, 2 * math.pi, 6.0, 100.0)
    samples = _motor_samples(simulation, offset)
    limited = np.abs(simulation.motor_torque) >= motor.max_torque
    assert np.count_nonzero(limited[simulation.time > 2.0]) > 10  # in every revolution
    drive = recorded_drive.Drive(mass, LOADS, motor)
    found = segments.setting_speed(samples, drive)
    steady = simulation.time > 1.0
    np.testing.assert_allclose(found[steady], 2 * math.pi, rtol=1e-13)
    pieces, _ = segments.split_segments(samples, [recorded_drive.DriveSpan(-math.inf, drive,
                                                                           None)])
    assert len(pieces) == 1


def test_a_motor_run_is_one_segment_per_setting_and_a_load_change_splits_it():
    motor = dyn.MotorDrive.small_shaper()
    mass = dyn.MassProperties.small_shaper()
    simulation = simulate(PAPER, mass, LOADS, motor, 0.01, 2 * math.pi, 4.0, 200.0)
    samples = _motor_samples(simulation)
    assert np.ptp(samples.input_speed) > 1e-3  # it fluctuates: no run of equal speeds
    heavier = dyn.Loads(2 * LOADS.cutting_force, LOADS.ram_friction, LOADS.cutting_length)
    spans = (recorded_drive.DriveSpan(-math.inf, recorded_drive.Drive(mass, LOADS, motor), None),
             recorded_drive.DriveSpan(2.0025, recorded_drive.Drive(mass, heavier, motor), None))
    # The simulation ran the first load throughout; only the segmenting is under test here.
    found, transitions = segments.split_segments(samples, spans[:1])
    assert [(s.start, s.end) for s in found] == [(0, samples.time.size)]
    assert found[0].input_speed == pytest.approx(2 * math.pi, rel=1e-13)
    found, transitions = segments.split_segments(samples, spans)
    assert [(s.start, s.end) for s in found] == [(0, 401), (401, samples.time.size)]
    assert [s.drive for s in found] == [span.drive for span in spans]
    assert transitions[0]['change'] == (
        f'cutting_force {LOADS.cutting_force!r} -> {heavier.cutting_force!r}')
