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
speed_drive.peak_input_torque against pair_efforts and dense sampling of dynamics.efforts.

dynamics.speed_drive_torque_of (the kernel's formula) is held to dynamics.efforts and its
slope to finite differences.
"""

import math
import os
from pathlib import Path
import subprocess
import sys

import numba
import numpy as np
import pytest

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics import speed_drive as sd
from qrm_ros.core.dynamics import torque_kernel
from repo_paths import REPO_ROOT

MASS = dyn.MassProperties.small_shaper()
PAPER = kin.Geometry.paper()


def random_designs(count, seed, offset_fraction=0.99):
    rng = np.random.default_rng(seed)
    r1 = rng.uniform(0.01, 0.05, count)
    h = rng.uniform(0.08, 0.2, count)
    r = h * rng.uniform(0.1, 0.95, count)
    geometry = kin.Geometry(r1, r, h, rng.uniform(0.15, 0.4, count),
                            rng.uniform(-math.pi, math.pi, count))
    offset = r1 * rng.uniform(-offset_fraction, offset_fraction, count)
    speed = rng.choice([-1.0, 1.0], count) * rng.uniform(1.0, 40.0, count)
    return geometry, offset, speed


def one(geometry, index):
    return kin.Geometry(*(float(value if np.ndim(value) == 0 else value[index])
                          for value in geometry.as_dict().values()))


def formula_arguments(geometry, offset, speed, force, mass=MASS):
    r1 = geometry.coupling_radius
    return (r1, geometry.crank_radius, geometry.pivot_distance, geometry.ram_height,
            math.cos(geometry.crank_phase), math.sin(geometry.crank_phase), offset,
            (r1 - offset) * (r1 + offset), speed, force, mass.flywheel_inertia,
            mass.lever_inertia, mass.ram_mass,
            mass.lever_mass * mass.gravity * mass.lever_com_distance)


def test_formula_and_slope_match_the_chain():
    geometry, offset, speed = random_designs(12, 3, offset_fraction=0.9)
    rng = np.random.default_rng(4)
    crank = np.linspace(0.0, 2.0 * math.pi, 4001)[:-1]
    for index in range(12):
        design = one(geometry, index)
        force = rng.uniform(-500.0, 500.0)
        arguments = formula_arguments(design, offset[index], speed[index], force)
        theta = kin.input_angle_for_flywheel_angle(design, offset[index],
                                                   crank - design.crank_phase)
        chain = dyn.efforts(design, MASS, offset[index], theta, speed[index],
                            external_ram_force=force).input_torque
        torque, slope = dyn.speed_drive_torque_of(np.sin(crank), np.cos(crank), *arguments)
        assert np.max(np.abs(torque - chain)) <= 1e-13 * np.max(np.abs(chain))
        step = 1e-6
        ahead, _ = dyn.speed_drive_torque_of(np.sin(crank + step), np.cos(crank + step),
                                             *arguments)
        behind, _ = dyn.speed_drive_torque_of(np.sin(crank - step), np.cos(crank - step),
                                              *arguments)
        difference = (ahead - behind) / (2.0 * step)
        assert np.max(np.abs(slope - difference)) <= 1e-8 * np.max(np.abs(slope))
        # The compiled formula is the same one.
        for k in range(0, crank.size, 400):
            compiled = torque_kernel.torque_of(math.sin(crank[k]), math.cos(crank[k]),
                                               *arguments)
            assert compiled[0] == pytest.approx(torque[k], rel=1e-14, abs=1e-14 * np.max(
                np.abs(chain)))
            assert compiled[1] == pytest.approx(slope[k], rel=1e-13, abs=1e-13 * np.max(
                np.abs(slope)))


LOADS = {
    'small shaper': dyn.Loads.small_shaper(),
    'none': dyn.Loads.none(),
    'no cutting': dyn.Loads(cutting_force=0.0, ram_friction=20.0, cutting_length=0.15),
    'whole stroke': dyn.Loads(cutting_force=400.0, ram_friction=20.0,
                              cutting_length=PAPER.ram_stroke),
    'heavy cut': dyn.Loads(cutting_force=5000.0, ram_friction=50.0, cutting_length=0.05),
}


@pytest.mark.parametrize('name', sorted(LOADS))
def test_paper_design_matches_pair_efforts(name):
    loads = LOADS[name]
    offsets = np.array([-0.0225, -0.01, 0.0, 0.007, 0.0225])
    speeds = np.array([2.0 * math.pi, -2.0 * math.pi, 30.0, -0.5])
    peaks = sd.peak_input_torque(PAPER, MASS, loads, offsets[:, None], speeds[None, :])
    assert peaks.shape == (5, 4)
    for i, offset in enumerate(offsets):
        for j, speed in enumerate(speeds):
            reference = sd.pair_efforts(PAPER, MASS, loads, float(offset), float(speed))
            assert peaks[i, j] == pytest.approx(reference.peak_input_torque, rel=1e-12)


def test_random_designs_match_pair_efforts():
    geometry, offset, speed = random_designs(40, 5)
    loads = dyn.Loads(400.0, 20.0, 0.8 * float(np.min(geometry.ram_stroke)))
    peaks = sd.peak_input_torque(geometry, MASS, loads, offset, speed)
    for index in range(40):
        design = one(geometry, index)
        reference = sd.pair_efforts(design, MASS, loads, offset[index], speed[index])
        # pair_efforts' own round-off grows as (r1 / (r1 - |offset|))^2 (its docstring).
        closeness = design.coupling_radius / (design.coupling_radius - abs(offset[index]))
        tolerance = 1e-12 * max(1.0, (0.1 * closeness) ** 2)
        assert peaks[index] == pytest.approx(reference.peak_input_torque, rel=tolerance)


def dense_peak(geometry, loads, offset, speed, samples=2_000_000):
    """Largest |torque| of dense input-angle samples and at the load switches; its bound."""
    theta = np.linspace(0.0, 2.0 * math.pi, samples, endpoint=False)
    motion = kin.state(geometry, offset, theta, speed)
    load = dyn.ram_load_force(loads, motion.ram_position, motion.ram_velocity,
                              geometry.ram_stroke)
    torque = dyn.efforts(geometry, MASS, offset, theta, speed,
                         external_ram_force=load).input_torque
    best = np.max(np.abs(torque))
    # One-sided values at the switches: each with the load just before and just after.
    for switch in sd.load_switch_angles(geometry, loads, offset):
        for side in (-1e-9, 1e-9):
            near = kin.state(geometry, offset, switch + side, speed)
            force = dyn.ram_load_force(loads, near.ram_position, near.ram_velocity,
                                       geometry.ram_stroke)
            value = dyn.efforts(geometry, MASS, offset, switch, speed,
                                external_ram_force=force).input_torque
            best = max(best, abs(value))
    # Between samples of one smooth piece the torque exceeds the nearer sample by at most
    # max|torque''| (spacing / 2)^2 / 2 (its slope is zero at an interior peak).
    same = (load[:-2] == load[1:-1]) & (load[1:-1] == load[2:])
    curvature = np.abs(torque[:-2] - 2.0 * torque[1:-1] + torque[2:])[same]
    return best, float(np.max(curvature)) / 8.0


@pytest.mark.parametrize('case', range(4))
def test_matches_dense_sampling(case):
    geometry, offset, speed = random_designs(4, 9)
    design, offset, speed = one(geometry, case), float(offset[case]), float(speed[case])
    if case == 0:
        design, offset, speed = PAPER, 0.015, -2.0 * math.pi
    loads = dyn.Loads(400.0, 20.0, 0.7 * design.ram_stroke)
    peak = sd.peak_input_torque(design, MASS, loads, offset, speed)
    dense, bound = dense_peak(design, loads, offset, speed)
    assert peak >= dense * (1.0 - 1e-13)
    assert peak <= dense + bound + 1e-13 * dense
    assert bound < 1e-7 * dense  # the samples alone pin the peak to 1e-7 at least


def test_broadcast_shapes_and_floats():
    loads = dyn.Loads.small_shaper()
    value = sd.peak_input_torque(PAPER, MASS, loads, 0.01, 2.0 * math.pi)
    assert type(value) is float
    radii = kin.Geometry(0.025, np.array([0.03, 0.04, 0.0505]), 0.113)
    peaks = sd.peak_input_torque(radii, MASS, dyn.Loads(400.0, 20.0, 0.05),
                                 np.array([[0.0], [0.01]]), 2.0 * math.pi)
    assert peaks.shape == (2, 3)
    for i, offset in enumerate((0.0, 0.01)):
        for j in range(3):
            reference = sd.pair_efforts(one(radii, j), MASS, dyn.Loads(400.0, 20.0, 0.05),
                                        offset, 2.0 * math.pi).peak_input_torque
            assert peaks[i, j] == pytest.approx(reference, rel=1e-12)


def test_refuses_bad_input():
    loads = dyn.Loads.small_shaper()
    with pytest.raises(kin.KinematicsError, match='input_speed must be non-zero'):
        sd.peak_input_torque(PAPER, MASS, loads, 0.01, np.array([1.0, 0.0]))
    with pytest.raises(kin.KinematicsError, match='offset 0.025 m is out of range'):
        sd.peak_input_torque(PAPER, MASS, loads, 0.025, 1.0)
    with pytest.raises(dyn.DynamicsError, match='input_speed must be finite'):
        sd.peak_input_torque(PAPER, MASS, loads, 0.01, math.nan)
    with pytest.raises(dyn.DynamicsError, match='cutting_length = 0.3 m is out of range'):
        sd.peak_input_torque(PAPER, MASS, dyn.Loads(400.0, 20.0, 0.3), 0.01, 1.0)
    heavy = dyn.MassProperties(1.2, 0.08, 0.15, 5.0, 0.15, np.array([20.0, 30.0]))
    with pytest.raises(dyn.DynamicsError, match='ram_mass must be a single number'):
        sd.peak_input_torque(PAPER, heavy, loads, 0.01, 1.0)


def test_order_does_not_change_results():
    """A configuration's peak is its own: the kernel's reuse of a repeated geometry or phase
    (consecutive configurations) gives the same floats as computing them afresh."""
    radii = kin.Geometry(0.025, np.linspace(0.02, 0.1, 40)[:, None], 0.113)
    offsets = np.linspace(-0.0225, 0.0225, 50)[None, :]
    loads = dyn.Loads(400.0, 20.0, 0.9 * float(np.min(radii.ram_stroke)))
    grid = sd.peak_input_torque(radii, MASS, loads, offsets, -2.0 * math.pi)
    order = np.random.default_rng(8).permutation(grid.size)
    crank = np.broadcast_to(radii.crank_radius, grid.shape).ravel()[order]
    shuffled = sd.peak_input_torque(kin.Geometry(0.025, crank, 0.113), MASS, loads,
                                    np.broadcast_to(offsets, grid.shape).ravel()[order],
                                    -2.0 * math.pi)
    np.testing.assert_array_equal(shuffled, grid.ravel()[order])


def test_thread_count_does_not_change_results():
    geometry, offset, speed = random_designs(20_000, 21)
    loads = dyn.Loads(400.0, 20.0, 0.8 * float(np.min(geometry.ram_stroke)))
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        alone = sd.peak_input_torque(geometry, MASS, loads, offset, speed)
    finally:
        numba.set_num_threads(threads)
    shared = sd.peak_input_torque(geometry, MASS, loads, offset, speed)
    np.testing.assert_array_equal(alone, shared)


def test_the_documented_sweep():
    """The design page's example: the offsets' peaks, each the same as pair_efforts' alone."""
    geometry = kin.Geometry.paper()
    mass, loads = dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper()
    offsets = np.array([-0.02, -0.01, 0.0, 0.01, 0.02])
    peaks = sd.peak_input_torque(geometry, mass, loads, offsets, 2 * math.pi)
    documented = ' '.join((Path(REPO_ROOT) / 'doc' / 'design.md').read_text().split())
    assert ('offsets −20, −10, 0, +10, +20 mm give 480.25, 48.128, 26.225, 104.72 and 2923.9 N·m'
            in documented)
    for offset, peak, shown in zip(offsets, peaks, (480.25, 48.128, 26.225, 104.72, 2923.9)):
        assert peak == pytest.approx(sd.pair_efforts(geometry, mass, loads, offset,
                                                     2 * math.pi).peak_input_torque,
                                     rel=1e-12)
        assert float(f'{peak:.5g}') == shown


_CONCURRENT_CALLS = '''
import math, threading
import numpy as np
from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.dynamics.speed_drive import peak_input_torque
geometry = Geometry.paper()
mass, loads = dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper()
offsets = np.linspace(-0.02, 0.02, 20000)
sums = []
def run():
    for _ in range(3):
        sums.append(float(peak_input_torque(geometry, mass, loads, offsets, 2 * math.pi).sum()))
threads = [threading.Thread(target=run) for _ in range(3)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
print(len(sums), len(set(sums)))
'''


def test_concurrent_callers_are_safe_on_any_threading_layer():
    """numba's workqueue layer aborts on concurrent parallel calls; the callers take turns."""
    result = subprocess.run([sys.executable, '-c', _CONCURRENT_CALLS], capture_output=True,
                            text=True, timeout=120,
                            env=dict(os.environ, NUMBA_THREADING_LAYER='workqueue'))
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ['9', '1']
