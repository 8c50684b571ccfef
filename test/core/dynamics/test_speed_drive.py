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
The ideal speed drive's exact figures against independent derivations.

pair_efforts: the work per revolution against the loads' path work in closed form (the cut
once over the workpiece, friction over twice the stroke; gravity and inertia give back what
they take), the RMS and peaks against dense sampling with no splitting at the switches.
"""

import math

import warnings

import numpy as np
import pytest
from scipy import integrate, optimize

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core.dynamics import speed_drive as sd
from qrm_ros.core.kinematics.geometry import Geometry, KinematicsError
from qrm_ros.core.kinematics import state
from synthetic_run import dense_revolution

PAPER_GEOMETRY = Geometry.paper()

GEOMETRY = Geometry.paper()
MASS = dyn.MassProperties.small_shaper()
LOADS = dyn.Loads.small_shaper()


def _dense_torques(offset, input_speed, samples=400001):
    return dense_revolution(GEOMETRY, MASS, LOADS, offset, input_speed, samples)


@pytest.mark.parametrize('offset, input_speed', [(0.0, 2 * math.pi), (0.015, 2 * math.pi),
                                                 (-0.01, 3.0), (0.012, -4.0)])
def test_pair_efforts_against_path_work_and_dense_sampling(offset, input_speed):
    figures = sd.pair_efforts(GEOMETRY, MASS, LOADS, offset, input_speed)
    # Cutting only happens on the stroke toward -x, which is the cut for a positive speed and
    # the return for a negative one: either way it crosses the workpiece once per pair.
    path_work = (LOADS.cutting_force * LOADS.cutting_length
                 + LOADS.ram_friction * 2 * GEOMETRY.ram_stroke)
    assert figures.energy_per_pair == pytest.approx(path_work, rel=1e-10)
    period = 2 * math.pi / abs(input_speed)
    assert figures.mean_input_power == pytest.approx(path_work / period, rel=1e-10)
    times, torque, force = _dense_torques(offset, input_speed)
    dense_rms = math.sqrt(np.trapezoid(torque ** 2, times) / period)
    # The trapezoid straddles each load jump: an error of about half the jump in torque^2
    # times one sample spacing per jump, ~1e-5 of the mean square here.
    assert figures.rms_input_torque == pytest.approx(dense_rms, rel=2e-5)
    assert figures.peak_input_torque >= np.max(np.abs(torque)) * (1 - 1e-12)
    assert figures.peak_input_torque == pytest.approx(np.max(np.abs(torque)), rel=1e-6)
    assert figures.peak_offset_force >= np.max(np.abs(force)) * (1 - 1e-12)
    assert figures.peak_offset_force == pytest.approx(np.max(np.abs(force)), rel=1e-6)


def test_pair_efforts_free_running_costs_nothing():
    figures = sd.pair_efforts(GEOMETRY, MASS, dyn.Loads.none(), 0.01, 5.0)
    assert abs(figures.energy_per_pair) < 1e-9
    assert figures.peak_input_torque > 0.0


def test_pair_efforts_refuses_bad_input():
    with pytest.raises(KinematicsError, match='input_speed'):
        sd.pair_efforts(GEOMETRY, MASS, LOADS, 0.0, 0.0)
    with pytest.raises(KinematicsError, match='offset'):
        sd.pair_efforts(GEOMETRY, MASS, LOADS, 0.03, 1.0)
    with pytest.raises(dyn.DynamicsError, match='cutting_length'):
        sd.pair_efforts(GEOMETRY, MASS, dyn.Loads(1.0, 1.0, 1.0), 0.0, 1.0)


# The former pair_efforts (numbers by scipy's quad, switches by brentq on 2048 samples a
# revolution, peaks by minimize_scalar), kept as the reference of the fast one. It refined
# 64 samples a piece, which missed narrow peaks near the coupling radius by up to 0.5 %; here
# it takes 1024.
_REFERENCE_SWITCH_SAMPLES = 2048
_REFERENCE_PEAK_SAMPLES = 1024


def _reference_switch_times(geometry, loads, offset, input_speed, period):
    def switching(time):
        motion = state(geometry, offset, input_speed * time, input_speed)
        half = 0.5 * loads.cutting_length
        return (motion.ram_velocity, motion.ram_position - half, motion.ram_position + half)

    times = np.linspace(0.0, period, _REFERENCE_SWITCH_SAMPLES + 1)
    switches = []
    for index, values in enumerate(switching(times)):
        changes = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0.0)[0]
        for change in changes:
            switches.append(optimize.brentq(lambda t: switching(t)[index], times[change],
                                            times[change + 1], xtol=1e-15 * period,
                                            rtol=4 * np.finfo(float).eps))
        switches.extend(times[1:-1][values[1:-1] == 0.0])
    return sorted(switches)


def _reference_peak(function, start, end):
    times = np.linspace(start, end, _REFERENCE_PEAK_SAMPLES)
    values = np.abs(function(times))
    best = int(np.argmax(values))
    peak = float(values[best])
    low, high = times[max(best - 1, 0)], times[min(best + 1, times.size - 1)]
    if high > low:
        result = optimize.minimize_scalar(lambda t: -abs(float(function(t))), bounds=(low, high),
                                          method='bounded',
                                          options={'xatol': 1e-14 * max(abs(end), 1.0)})
        peak = max(peak, -float(result.fun))
    return peak


def _reference_pair_efforts(geometry, mass, loads, offset, input_speed):
    period = 2.0 * math.pi / abs(input_speed)
    bounds = [0.0, *_reference_switch_times(geometry, loads, offset, input_speed, period),
              period]
    energy = square = peak_torque = peak_force = 0.0
    for start, end in zip(bounds[:-1], bounds[1:]):
        if end <= start:
            continue
        middle = state(geometry, offset, input_speed * 0.5 * (start + end), input_speed)
        load = dyn.ram_load_force(loads, middle.ram_position, middle.ram_velocity,
                                  geometry.ram_stroke)

        def piece(time, load=load):
            return dyn.efforts(geometry, mass, offset, input_speed * np.asarray(time),
                               input_speed, external_ram_force=load)

        def torque(time):
            return piece(time).input_torque

        tolerance = {'epsabs': 0.0, 'epsrel': 1e-12, 'limit': 200}
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', integrate.IntegrationWarning)
            energy += input_speed * integrate.quad(torque, start, end, **tolerance)[0]
            square += integrate.quad(lambda t: torque(t) ** 2, start, end, **tolerance)[0]
        peak_torque = max(peak_torque, _reference_peak(torque, start, end))
        peak_force = max(peak_force, _reference_peak(lambda t: piece(t).offset_force, start,
                                                     end))
    return sd.PairEfforts(peak_input_torque=peak_torque,
                          rms_input_torque=math.sqrt(square / period),
                          mean_input_power=energy / period, energy_per_pair=energy,
                          peak_offset_force=peak_force)


def _random_design(rng):
    """A geometry, masses, loads and offset (within the safe range) drawn at random."""
    pivot = rng.uniform(0.08, 0.2)
    geometry = Geometry(coupling_radius=rng.uniform(0.01, 0.05),
                        crank_radius=rng.uniform(0.2, 0.8) * pivot, pivot_distance=pivot,
                        ram_height=rng.uniform(0.1, 0.4),
                        crank_phase=rng.uniform(-1.0, 1.0) if rng.random() < 0.5 else 0.0)
    mass = dyn.MassProperties(
        input_inertia=rng.uniform(0.0, 2.0), flywheel_inertia=rng.uniform(0.01, 1.0),
        lever_inertia=rng.uniform(0.0, 0.5), lever_mass=rng.uniform(0.0, 10.0),
        lever_com_distance=rng.uniform(-0.1, 0.3), ram_mass=rng.uniform(0.0, 50.0))
    # Half the workpieces are as long as the stroke (their edges are the reversals).
    loads = dyn.Loads(cutting_force=rng.choice([0.0, rng.uniform(0.0, 2000.0)]),
                      ram_friction=rng.choice([0.0, rng.uniform(0.0, 100.0)]),
                      cutting_length=geometry.ram_stroke * rng.choice([1.0, rng.random()]))
    offset = rng.uniform(-1.0, 1.0) * geometry.max_safe_offset
    return geometry, mass, loads, offset


def test_pair_efforts_against_the_quad_reference_on_random_designs():
    rng = np.random.default_rng(9)
    for _ in range(24):
        geometry, mass, loads, offset = _random_design(rng)
        speed = rng.uniform(0.5, 20.0)
        for input_speed in (speed, -speed):
            fast = sd.pair_efforts(geometry, mass, loads, offset, input_speed)
            reference = _reference_pair_efforts(geometry, mass, loads, offset, input_speed)
            # The work is what is left of a torque that swings both ways: compare it to the
            # revolution's integral of |torque| (at most 2 pi times the RMS torque).
            work_scale = 2 * math.pi * reference.rms_input_torque
            assert fast.energy_per_pair == pytest.approx(reference.energy_per_pair, rel=1e-12,
                                                         abs=1e-12 * work_scale)
            period = 2 * math.pi / speed
            assert fast.mean_input_power == pytest.approx(
                reference.mean_input_power, rel=1e-12, abs=1e-12 * work_scale / period)
            for name in ('rms_input_torque', 'peak_input_torque', 'peak_offset_force'):
                assert getattr(fast, name) == pytest.approx(getattr(reference, name),
                                                            rel=1e-12), name


def test_pair_efforts_finds_narrow_peaks_near_the_coupling_radius():
    # At 0.87 r1 backward the torque peak is narrow: 64 samples a piece missed it by 0.5 %.
    offset, input_speed = -0.87 * GEOMETRY.coupling_radius, -11.8
    figures = sd.pair_efforts(GEOMETRY, MASS, LOADS, offset, input_speed)
    times, torque, force = _dense_torques(offset, input_speed, samples=2000001)
    assert figures.peak_input_torque >= np.max(np.abs(torque)) * (1 - 1e-12)
    assert figures.peak_input_torque == pytest.approx(np.max(np.abs(torque)), rel=1e-9)
    assert figures.peak_offset_force >= np.max(np.abs(force)) * (1 - 1e-12)
    assert figures.peak_offset_force == pytest.approx(np.max(np.abs(force)), rel=1e-9)


def test_pair_efforts_near_the_coupling_radius_stays_at_round_off():
    # The torque's own round-off grows as eps r1^2 / (r1 - |offset|)^2: the quadrature stops
    # there instead of halving forever, and the work still closes on the path work.
    path_work = (LOADS.cutting_force * LOADS.cutting_length
                 + LOADS.ram_friction * 2 * GEOMETRY.ram_stroke)
    for fraction in (0.98, -0.999):
        offset = fraction * GEOMETRY.coupling_radius
        figures = sd.pair_efforts(GEOMETRY, MASS, LOADS, offset, 5.0)
        round_off = 1e-14 / (1 - abs(fraction)) ** 2
        assert figures.energy_per_pair == pytest.approx(
            path_work, abs=round_off * 2 * math.pi * figures.rms_input_torque)


@pytest.mark.parametrize('fraction', [0.9999, 0.99999, 1 - 4e-7])
def test_the_effort_integrals_stop_at_their_bound_near_the_coupling_radius(fraction):
    # Within 0.999 r1 they converge in a few hundred panels; nearer, the round-off floor kept
    # them splitting without end (gigabytes): now they stop at MAX_EFFORT_PANELS and say so.
    mass, loads = dyn.MassProperties.small_shaper(), dyn.Loads.small_shaper()
    with pytest.raises(sd.ToleranceUnreachable, match=f'{sd.MAX_EFFORT_PANELS} panels'):
        sd.pair_efforts(PAPER_GEOMETRY, mass, loads, fraction * PAPER_GEOMETRY.coupling_radius,
                        2 * math.pi)
    assert isinstance(sd.ToleranceUnreachable('x'), KinematicsError)  # commands catch it
    figures = sd.pair_efforts(PAPER_GEOMETRY, mass, loads,
                              0.999 * PAPER_GEOMETRY.coupling_radius, 2 * math.pi)
    assert math.isfinite(figures.peak_input_torque)
