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
Tests of qrm_design's drive figures and of ``qrm_design flywheel``.

Every printed number against an independent derivation: the torque columns against
``dynamics.efforts`` sampled densely over a revolution (no splitting at the load switches),
energy and power against the loads' path work in closed form, Cs against ``simulate`` sampled
at 5 kHz, the energy method against its own dense quadrature, the mean inertias against the
kinematics core's velocities (and mean (dphi/dtheta)^2 against its closed form), and the
sized inertias by simulating them again.
"""

from contextlib import redirect_stdout
import io
import json
import math
from pathlib import Path
import re

import numpy as np
import pytest
from scipy import integrate

from qrm_ros.analysis import design_table
from qrm_ros.cli import arguments
from qrm_ros.cli import qrm_design
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.motor.motor_stepper import simulate
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.kinematics import state

import synthetic_run
from repo_paths import REPO_ROOT

GEOMETRY = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()
MOTOR = dyn.MotorDrive.small_shaper()
SPEED = 2 * math.pi
# Where the worked examples of qrm_design are documented.
DESIGN_PAGE = Path(REPO_ROOT) / 'doc' / 'design.md'


def run_design(argv, capsys):
    code = qrm_design.main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def dense_revolution(offset, input_speed=SPEED, mass=MASS, loads=LOADS, samples=400001):
    return synthetic_run.dense_revolution(GEOMETRY, mass, loads, offset, input_speed, samples)


def path_work(loads=LOADS):
    """Work of the loads per pair: the cut once over the workpiece, friction over 2 strokes."""
    return loads.cutting_force * loads.cutting_length + loads.ram_friction * 2 * (
        GEOMETRY.ram_stroke)


def simulated_fluctuation(mass, offset, duration, motor=MOTOR, rate=5000.0):
    """Cs of the last whole revolution of an independent 5 kHz simulation."""
    run = simulate(GEOMETRY, mass, LOADS, motor, offset, SPEED, duration, rate)
    turns = np.floor(run.input_angle / (2 * math.pi))
    last = turns == turns[-1] - 1
    times = run.time[last]
    return np.ptp(run.input_speed[last]) / (2 * math.pi / (times[-1] - times[0]))


def drive_rows(text):
    """Rows of the drive block: 6 numbers (7 with Cs, '--' for a Cs not found)."""
    rows = []
    block = text.split('  offset  peak tau_in')[1]
    for line in block.splitlines()[2:]:
        fields = line.split()
        if not fields or not re.fullmatch(r'-?\d+\.\d\d', fields[0]):
            break
        rows.append([None if f == '--' else float(f) for f in fields])
    return rows


@pytest.fixture(scope='module')
def table():
    """The default table as JSON and as text."""
    outputs = []
    for argv in (['--json'], []):
        buffer = io.StringIO()
        with redirect_stdout(buffer):
            assert qrm_design.main(argv) == 0
        outputs.append(buffer.getvalue())
    return json.loads(outputs[0]), outputs[1]


def test_table_json_holds_its_inputs(table):
    data, _ = table
    assert Geometry(**data['geometry']).as_dict() == GEOMETRY.as_dict()
    assert data['input_speed'] == SPEED and data['ram_stroke'] == GEOMETRY.ram_stroke
    assert data['mass_properties'] == MASS.as_dict()
    assert data['loads'] == LOADS.as_dict()
    assert data['motor'] is None  # Cs is opt-in
    assert [row['offset'] for row in data['rows']] == pytest.approx(
        list(design_table.DEFAULT_OFFSETS_MM / 1e3), abs=1e-15)
    assert data['max_safe_offset'] == GEOMETRY.max_safe_offset
    assert data['offset_for_unity_speed_ratio'] == pytest.approx(
        -GEOMETRY.crank_radius * GEOMETRY.coupling_radius / GEOMETRY.pivot_distance, rel=1e-12)
    assert [entry['time_ratio'] for entry in data['offsets_for_time_ratio']] == [1.0, 2.0, 3.0]


def test_table_json_kinematics_are_the_text_table(table):
    data, text = table
    rows = [line.split() for line in text.splitlines()
            if len(line.split()) == 9 and re.fullmatch(r'-?\d+\.\d\d', line.split()[0])]
    assert len(rows) == len(data['rows'])
    keys = ['offset_over_pivot_distance', 'time_ratio', 'speed_ratio', 'peak_speed_ratio',
            'cutting_time', 'return_time', 'peak_cutting_speed', 'peak_return_speed']
    for fields, row in zip(rows, data['rows']):
        assert float(fields[0]) == pytest.approx(row['offset'] * 1e3, abs=6e-3)
        for field, key in zip(fields[1:], keys):
            decimals = len(field.split('.')[1])
            assert float(field) == pytest.approx(row[key], abs=0.6 * 10 ** -decimals)
    for entry in data['offsets_for_time_ratio']:
        assert f'TR = {entry["time_ratio"]:g} at offset {entry["offset"] * 1e3:.6f} mm' in text


def test_drive_columns_against_dense_sampling_and_path_work(table):
    data, text = table
    printed = drive_rows(text)
    assert len(printed) == len(data['rows'])
    work = path_work()
    for fields, row in zip(printed, data['rows']):
        offset_mm, peak, rms, power, energy, force = fields
        # The text is the JSON, rounded.
        assert offset_mm == pytest.approx(row['offset'] * 1e3, abs=6e-3)
        for value, key in ((peak, 'peak_input_torque'), (rms, 'rms_input_torque'),
                           (power, 'mean_input_power'), (energy, 'energy_per_pair')):
            assert value == pytest.approx(row[key], abs=6e-5)
        assert force == pytest.approx(row['peak_offset_force'], abs=6e-4)
        # The JSON against independent derivations.
        times, torque, offset_force = dense_revolution(row['offset'])
        period = times[-1]
        assert row['energy_per_pair'] == pytest.approx(work, rel=1e-9)
        assert row['mean_input_power'] == pytest.approx(work / period, rel=1e-9)
        assert row['rms_input_torque'] == pytest.approx(
            math.sqrt(integrate.trapezoid(torque ** 2, times) / period), rel=1e-5)
        # Dense samples can only miss a peak from below, by little.
        assert np.max(np.abs(torque)) <= row['peak_input_torque'] * (1 + 1e-9)
        assert np.max(np.abs(torque)) == pytest.approx(row['peak_input_torque'], rel=1e-5)
        assert np.max(np.abs(offset_force)) <= row['peak_offset_force'] * (1 + 1e-9)
        assert np.max(np.abs(offset_force)) == pytest.approx(row['peak_offset_force'],
                                                             rel=1e-5)
    assert 'add --speed-fluctuation' in text


def test_drive_columns_follow_the_options(capsys):
    argv = ['--json', '--offsets-mm', '-5', '7.5', '--input-speed', '3', '--ram-mass', '35',
            '--flywheel-inertia', '0.3', '--cutting-force', '900', '--ram-friction', '0',
            '--cutting-length', '0.1']
    code, out, _ = run_design(argv, capsys)
    assert code == 0
    data = json.loads(out)
    mass = dyn.MassProperties(**{**MASS.as_dict(), 'ram_mass': 35.0, 'flywheel_inertia': 0.3})
    loads = dyn.Loads(900.0, 0.0, 0.1)
    assert data['mass_properties'] == mass.as_dict() and data['loads'] == loads.as_dict()
    for row in data['rows']:
        times, torque, _ = dense_revolution(row['offset'], 3.0, mass, loads)
        assert row['energy_per_pair'] == pytest.approx(90.0, rel=1e-9)  # 900 N over 0.1 m
        assert row['mean_input_power'] == pytest.approx(90.0 * 3.0 / (2 * math.pi), rel=1e-9)
        assert row['rms_input_torque'] == pytest.approx(
            math.sqrt(integrate.trapezoid(torque ** 2, times) / times[-1]), rel=1e-5)
        assert row['peak_input_torque'] == pytest.approx(np.max(np.abs(torque)), rel=1e-5)


def test_speed_fluctuation_column_against_simulation(capsys):
    argv = ['--speed-fluctuation', '--offsets-mm', '0', '5', '--motor-speed-stiffness', '300']
    code, out, _ = run_design(argv + ['--json'], capsys)
    assert code == 0
    data = json.loads(out)
    text = design_table.format_design_table(data)  # what main prints without --json
    motor = dyn.MotorDrive(300.0, MOTOR.max_torque)
    assert data['motor'] == motor.as_dict()
    rows = drive_rows(text)
    assert [len(row) for row in rows] == [7, 7]
    for fields, row in zip(rows, data['rows']):
        assert fields[6] == pytest.approx(row['speed_fluctuation'], abs=6e-7)
        assert row['speed_fluctuation'] == pytest.approx(
            simulated_fluctuation(MASS, row["offset"], 2.5, motor), rel=2e-3)
    assert 'speed_stiffness 300 N*m*s/rad' in text


def test_a_stalling_row_says_why(capsys):
    argv = ['--speed-fluctuation', '--offsets-mm', '0', '--motor-max-torque', '1']
    code, text, _ = run_design(argv, capsys)
    assert code == 0
    assert drive_rows(text)[0][6] is None
    assert re.search(r'offset 0 mm, Cs: the machine stalls: .*max_torque 1 N\*m', text)
    _, out, _ = run_design(argv + ['--json'], capsys)
    row = json.loads(out)['rows'][0]
    assert row['speed_fluctuation'] is None
    assert row['speed_fluctuation_problem'].startswith('the machine stalls')


@pytest.mark.parametrize('extra, words', [
    (['--ram-mass', '-1'], 'ram_mass = -1.0 kg is out of range: allowed >= 0 kg'),
    (['--cutting-length', '0.3'], 'cutting_length = 0.3 m is out of range: allowed 0 to'),
    (['--input-inertia', '0', '--flywheel-inertia', '0'], 'at least one must be > 0'),
    (['--motor-speed-stiffness', '0', '--speed-fluctuation'],
     'speed_stiffness = 0.0 N*m*s/rad is out of range: allowed > 0'),
    (['--input-speed', '-1', '--speed-fluctuation'], 'input_speed must be > 0 rad/s'),
    (['--input-speed', 'nan'], 'input_speed'),
    # Finite but absurd: each refused with the range a shaper never leaves.
    (['--input-speed', '1e300'], '--input-speed (input_speed) = 1e+300 rad/s is out of range: '
                                 'allowed '
                                 '0.001 <= |input speed| <= 10000 rad/s'),
    (['--lever-mass', '1e308', '--gravity', '1e308'], 'lever_mass = 1e+308 kg is out of range'),
    (['--motor-speed-stiffness', '1e12', '--speed-fluctuation'],
     '|speed_stiffness| <= 1e+06 N*m*s/rad'),
    (['--motor-speed-stiffness', '1e6', '--speed-fluctuation'],
     "the motor drive's time constant"),
    (['--motor-max-torque', '1e-12', '--speed-fluctuation'], 'the motor saturates within'),
])
def test_table_bad_drive_numbers_exit_2(capsys, extra, words):
    code, out, err = run_design(['--offsets-mm', '0'] + extra, capsys)
    assert code == 2 and out == ''
    assert err.startswith('qrm_design: ') and words in err
    assert len(err.strip().splitlines()) == 1


# qrm_design flywheel --------------------------------------------------------------------

FLYWHEEL_ARGS = ['flywheel', '--fluctuation', '0.05', '--offset', '0.01']


@pytest.fixture(scope='module')
def sized():
    """The design page's worked example, as JSON (the default motor: fast to simulate)."""
    buffer = io.StringIO()
    with redirect_stdout(buffer):
        assert qrm_design.main(FLYWHEEL_ARGS + ['--json']) == 0
    return json.loads(buffer.getvalue())


def test_flywheel_json_holds_its_inputs(sized):
    assert Geometry(**sized['geometry']).as_dict() == GEOMETRY.as_dict()
    assert (sized['offset'], sized['input_speed']) == (0.01, SPEED)
    assert sized['mass_properties'] == MASS.as_dict() and sized['loads'] == LOADS.as_dict()
    assert sized['motor'] == MOTOR.as_dict()
    assert sized['speed_fluctuation'] == 0.05
    assert sized['added_input_inertia'] == pytest.approx(
        sized['input_inertia'] - MASS.input_inertia, rel=1e-15)


def test_sized_input_inertia_gives_the_asked_fluctuation_when_simulated(sized):
    mass = dyn.MassProperties(**{**MASS.as_dict(), 'input_inertia': sized['input_inertia']})
    # J1 / k is 0.04 s: steady long before the second revolution.
    assert simulated_fluctuation(mass, 0.01, 2.5) == pytest.approx(0.05, rel=0.01)
    assert sized['simulated_speed_fluctuation'] == pytest.approx(0.05, rel=0.01)
    assert sized['given_speed_fluctuation'] == pytest.approx(
        simulated_fluctuation(MASS, 0.01, 2.5), rel=2e-3)


def test_energy_method_and_mean_inertias_against_independent_derivations(sized):
    offset = sized['offset']
    # Energy method: Delta E from the dense torque, by its own cumulative quadrature.
    times, torque, _ = dense_revolution(offset)
    angles = SPEED * times
    excess = integrate.cumulative_trapezoid(torque - integrate.trapezoid(torque, angles)
                                            / angles[-1], angles, initial=0.0)
    assert sized['energy_method_inertia'] == pytest.approx(
        np.ptp(excess) / (0.05 * SPEED ** 2), rel=1e-4)
    # Mean inertias over a revolution from the kinematics core's speeds at unit input speed.
    r1 = GEOMETRY.coupling_radius

    def mean(function):
        return integrate.quad(function, 0.0, 2 * math.pi, epsabs=0.0, epsrel=1e-12,
                              limit=200)[0] / (2 * math.pi)

    def kinetic(angle):
        motion = state(GEOMETRY, offset, angle, 1.0)
        return (MASS.flywheel_inertia * motion.flywheel_speed ** 2
                + MASS.lever_inertia * motion.lever_speed ** 2
                + MASS.ram_mass * motion.ram_velocity ** 2)
    assert sized['chain_mean_inertia'] == pytest.approx(mean(kinetic), rel=1e-10)
    ratio = mean(lambda angle: state(GEOMETRY, offset, angle, 1.0).flywheel_speed ** 2)
    assert sized['flywheel_mean_square_ratio'] == pytest.approx(ratio, rel=1e-10)
    # ... which is (r1^2 - offset^2 / 2) / (r1^2 - offset^2) in closed form.
    assert ratio == pytest.approx((r1 ** 2 - offset ** 2 / 2) / (r1 ** 2 - offset ** 2),
                                  rel=1e-10)
    assert sized['energy_method_input_inertia'] == pytest.approx(
        sized['energy_method_inertia'] - sized['chain_mean_inertia'], rel=1e-12)


def test_equivalent_flywheel_is_simulated_again(sized):
    added = sized['input_inertia'] - MASS.input_inertia
    flywheel = MASS.flywheel_inertia + added / sized['flywheel_mean_square_ratio']
    assert sized['equivalent_flywheel_inertia'] == pytest.approx(flywheel, rel=1e-12)
    mass = dyn.MassProperties(**{**MASS.as_dict(), 'flywheel_inertia': flywheel})
    assert sized['equivalent_speed_fluctuation'] == pytest.approx(
        simulated_fluctuation(mass, 0.01, 2.5), rel=2e-3)
    # With the offset, the flywheel on the crank shaft does the job far worse than on the input.
    assert sized['equivalent_speed_fluctuation'] > 5 * sized['speed_fluctuation']


def test_flywheel_text_prints_the_json_numbers(sized):
    text = design_table.format_flywheel(sized)
    numbers = {
        'given': r'given J1 = ([\d.]+) kg\*m\^2: Cs = ([\d.]+)',
        'sized': r'J1 for Cs = 0\.05: ([\d.]+) kg\*m\^2 \(refined by simulation\), '
                 r'([+-][\d.]+) kg\*m\^2 on the given J1',
        'again': r'simulated again with it: Cs = ([\d.]+)',
        'energy': r'Delta E / \(Cs w\^2\) = ([\d.]+) kg\*m\^2',
        'chain': r'mean share, ([\d.]+) kg\*m\^2: J1 = ([\d.]+) kg\*m\^2',
        'flywheel': r'flywheel_inertia J2 = ([\d.]+) kg\*m\^2',
        'ratio': r'mean \(dphi/dtheta\)\^2, mean = ([\d.]+)\)',
        'equivalent': r'simulated with it: Cs = ([\d.]+)',
    }
    keys = {
        'given': ['input_inertia', 'given_speed_fluctuation'],
        'sized': ['input_inertia', 'added_input_inertia'],
        'again': ['simulated_speed_fluctuation'], 'energy': ['energy_method_inertia'],
        'chain': ['chain_mean_inertia', 'energy_method_input_inertia'],
        'flywheel': ['equivalent_flywheel_inertia'], 'ratio': ['flywheel_mean_square_ratio'],
        'equivalent': ['equivalent_speed_fluctuation'],
    }
    for name, pattern in numbers.items():
        found = re.search(pattern, text).groups()
        for value, key in zip(found, keys[name]):
            expected = MASS.input_inertia if (name, key) == ('given', 'input_inertia') else (
                sized[key])
            assert float(value) == pytest.approx(expected, rel=6e-6), (name, key)
    assert max(len(line) for line in text.splitlines()) <= 99


NUMBER = r'([-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?)'


def test_documented_worked_example_is_the_sizing(sized):
    """The design page's output of `qrm_design flywheel --fluctuation 0.05 --offset 0.01`."""
    example = re.search(r'\$ python3 dev\.py run qrm_design flywheel --fluctuation 0\.05 '
                        r'--offset 0\.01\n(.*?)```', DESIGN_PAGE.read_text(), re.S).group(1)
    documented = re.split(NUMBER, example.strip())
    printed = re.split(NUMBER, design_table.format_flywheel(sized).strip())
    # The words exactly; the numbers within 0.1 % (the simulations' settling and root
    # tolerances are 1e-4: a faster motor drive may move the last printed digit).
    assert documented[::2] == printed[::2]
    assert [float(n) for n in documented[1::2]] == pytest.approx(
        [float(n) for n in printed[1::2]], rel=1e-3)


def test_documented_figures_of_the_drive_columns(table):
    data, _ = table
    rows = {round(row['offset'] * 1e3, 2): row for row in data['rows']}
    documented = ' '.join(DESIGN_PAGE.read_text().split())
    for offset_mm, text in ((0.0, '26.225 N·m at δ = 0'), (10.0, '104.72 N·m at +10 mm'),
                            (20.0, '2923.9 N·m at +20 mm'), (-20.0, '480.25 N·m at −20 mm')):
        assert text in documented
        shown = float(text.split()[0])
        assert rows[offset_mm]['peak_input_torque'] == pytest.approx(shown, rel=1e-4)
    assert '20 × 2 × 0.19983 = 67.993 J' in documented
    assert rows[0.0]['energy_per_pair'] == pytest.approx(67.993, abs=5e-4)
    # The crank's speed range at 10 mm: r1 / (r1 + offset) to r1 / (r1 - offset).
    angles = np.linspace(0.0, 2 * math.pi, 100001)
    ratio = state(GEOMETRY, 0.01, angles, 1.0).flywheel_speed
    assert (np.min(ratio), np.max(ratio)) == pytest.approx((25 / 35, 25 / 15), rel=1e-9)
    assert 'r1 / (r1 + δ) = 0.714 and r1 / (r1 − δ) = 1.667' in documented


def test_flywheel_at_offset_zero_is_the_same_machine(capsys):
    # At offset 0, d(phi)/d(theta) = 1: J2 adds to M exactly as J1 does.
    code, text, _ = run_design(['flywheel', '--fluctuation', '0.015', '--cutting-force', '200'],
                               capsys)
    assert code == 0
    sized = float(re.search(r'J1 for Cs = 0\.015: ([\d.]+) kg', text).group(1))
    flywheel = float(re.search(r'flywheel_inertia J2 = ([\d.]+) kg', text).group(1))
    assert flywheel == pytest.approx(MASS.flywheel_inertia + sized - MASS.input_inertia,
                                     rel=1e-5)
    again, equivalent = (float(value) for value in re.findall(
        r'simulated (?:again )?with it: Cs = ([\d.]+)', text))
    assert again == pytest.approx(0.015, rel=0.01)
    assert equivalent == pytest.approx(again, rel=1e-3)
    assert 'mean = 1)' in text and '(at offset 0 the same machine)' in text


@pytest.mark.parametrize('extra, words', [
    (['--fluctuation', '0.5'], 'fluctuation = 0.5 is out of range: with input_inertia >= 0 '
                               'kg*m^2 this drive reaches 0 < Cs < 0.0201'),
    (['--fluctuation', '-0.1'], 'fluctuation must be > 0'),
    (['--fluctuation', '0.01', '--offset', '0.03'], 'offset 0.03 m is out of range'),
    (['--fluctuation', '0.01', '--input-speed', '0'], 'input_speed must be > 0'),
    (['--fluctuation', '0.01', '--motor-max-torque', '-3'],
     'max_torque = -3.0 N*m is out of range: allowed > 0 N*m'),
    (['--fluctuation', '0.01', '--lever-mass', 'inf'], 'lever_mass must be finite'),
    (['--fluctuation', '0.01', '--cutting-length', '0.5'], 'cutting_length = 0.5 m'),
    (['--fluctuation', '0.01', '--motor-max-torque', '1'],
     'the machine stalls: stalled at input angle'),
    (['--fluctuation', '1e-300'], 'fluctuation = 1e-300 (1) is out of range: allowed '
                                  '[0.0001, 0.5] (1)'),
    (['--fluctuation', '0.01', '--input-speed', '1e300'], 'input_speed = 1e+300 rad/s is out'),
    (['--fluctuation', '0.01', '--motor-max-torque', '1e-12'], 'the motor saturates within'),
    (['--fluctuation', '0.01', '--motor-max-torque', '1e-3'], 'the machine stalls'),
])
def test_flywheel_refusals_are_one_line_exit_2(capsys, extra, words):
    code, out, err = run_design(['flywheel'] + extra, capsys)
    assert code == 2 and out == ''
    assert err.startswith('qrm_design flywheel: ') and words in err
    assert len(err.strip().splitlines()) == 1


def test_flywheel_usage_errors_exit_2(capsys):
    for argv in (['flywheel'], ['flywheel', '--fluctuation', 'small']):
        with pytest.raises(SystemExit) as stopped:
            qrm_design.main(argv)
        assert stopped.value.code == 2
    with pytest.raises(SystemExit):
        qrm_design.main(['--help'])
    assert 'qrm_design flywheel --help' in capsys.readouterr().out


def test_documented_speed_fluctuation_at_the_largest_default_offset(capsys):
    # The motor saturates at +20 mm (once the slowest row of the Cs column).
    code, out, _ = run_design(['--speed-fluctuation', '--offsets-mm', '20', '--json'], capsys)
    assert code == 0
    fluctuation = json.loads(out)['rows'][0]['speed_fluctuation']
    assert '+20 mm the motor saturates: Cs = 1.08' in ' '.join(DESIGN_PAGE.read_text().split())
    assert fluctuation == pytest.approx(1.08, abs=5e-3)
    assert fluctuation == pytest.approx(simulated_fluctuation(MASS, 0.02, 4.0), rel=1e-2)


def test_drive_options_are_the_node_parameter_names():
    from qrm_ros.node.shaper_sim import shaper_parameters
    names = {name for kind, prefix, _ in arguments.DRIVE_PARAMETER_SETS
             for name in (prefix + field for field in kind.field_names())}
    assert names <= set(shaper_parameters.PARAMETERS)


def test_documented_speed_fluctuation_figures(sized, capsys):
    code, out, _ = run_design(['--speed-fluctuation', '--offsets-mm', '0', '15', '--json'],
                              capsys)
    assert code == 0
    at_zero, at_fifteen = (row['speed_fluctuation'] for row in json.loads(out)['rows'])
    assert ('goes from 0.020 at δ = 0 to 0.086 at +10 mm and 0.30 at +15 mm'
            in ' '.join(DESIGN_PAGE.read_text().split()))
    assert round(at_zero, 3) == 0.020 and round(at_fifteen, 2) == 0.30
    assert round(sized['given_speed_fluctuation'], 3) == 0.086
