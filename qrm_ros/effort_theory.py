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
The theory of one stroke pair's effort figures at a steady setting (pure numpy/scipy).

The analysis and the node compare what they measure with the same answers: the ideal speed
drive's exact figures (motor_drive.pair_efforts) or the motor drive's steady running
(motor_drive.speed_fluctuation). The motor drive's answer takes a simulation of many
revolutions, far longer than a node's tick, so ``BackgroundTheory`` works it out in a
worker process and the node picks it up once it is there: no tick waits for it.
"""

import contextlib
import math
import multiprocessing
import multiprocessing.pool
import os
import signal
import warnings
from typing import Dict, NamedTuple, Optional

from scipy import integrate

from qrm_ros import dynamics as dyn
from qrm_ros import kinematics as kin
from qrm_ros import motor_drive

__all__ = ['BackgroundTheory', 'EFFORT_FIGURES', 'Setting', 'steady_effort_theory',
           'THEORY_FIGURES', 'ZERO_CAN_BE_EXACT']

# Per-pair effort figures (strokes.measure_pair_efforts), in the order of the tables.
EFFORT_FIGURES = ('peak_input_torque', 'rms_input_torque', 'mean_input_power',
                  'energy_per_pair', 'peak_offset_force')
# Every figure the theory gives per pair.
THEORY_FIGURES = EFFORT_FIGURES + ('speed_fluctuation',)
# Figures whose theory can be exactly 0 (no loads: inertia and gravity give back over a
# revolution what they take; the ideal speed drive: no fluctuation). Their error is also
# given as measured - theory, the only error of a zero theory.
ZERO_CAN_BE_EXACT = ('mean_input_power', 'energy_per_pair', 'speed_fluctuation')
# A theoretical work per pair below this fraction of RMS torque x 2 pi is roundoff of 0.
_ROUNDOFF = 1e-9


class Setting(NamedTuple):
    """What the steady theory of a pair depends on (motor None: the ideal speed drive)."""

    geometry: kin.Geometry
    mass: dyn.MassProperties
    loads: dyn.Loads
    motor: Optional[dyn.MotorDrive]
    offset: float       # m
    input_speed: float  # rad/s: the drive's speed, or the motor's speed reference

    def key(self):
        """Return the setting's values, hashable (the parameter sets compare by identity)."""
        def values(part):
            return None if part is None else tuple(sorted(part.as_dict().items()))
        geometry = tuple(getattr(self.geometry, name) for name in kin.Geometry.field_names())
        return (geometry, values(self.mass), values(self.loads), values(self.motor),
                float(self.offset), float(self.input_speed))


def steady_effort_theory(setting: Setting) -> Dict[str, Optional[float]]:
    """
    Return the drive's figures of one pair at a steady setting, name -> value.

    None where there is no theory: a stopped shaft, a setting the core refuses (an offset at
    the coupling radius, a speed too large to be finite) or a motor that stalls.
    """
    theory: Dict[str, Optional[float]] = dict.fromkeys(THEORY_FIGURES)
    if setting.input_speed == 0.0:
        return theory
    geometry, mass, loads = setting.geometry, setting.mass, setting.loads
    with contextlib.suppress(kin.KinematicsError), warnings.catch_warnings():
        # quad warns of roundoff when its 1e-12 goal is met to within roundoff already.
        warnings.simplefilter('ignore', integrate.IntegrationWarning)
        if setting.motor is None:  # the ideal speed drive holds the speed: no fluctuation
            figures = motor_drive.pair_efforts(geometry, mass, loads, setting.offset,
                                               setting.input_speed)
            if (loads.cutting_force == 0.0 and loads.ram_friction == 0.0
                    and abs(figures.energy_per_pair)
                    <= _ROUNDOFF * 2 * math.pi * figures.rms_input_torque):
                figures = figures._replace(energy_per_pair=0.0, mean_input_power=0.0)
            theory.update(figures._asdict(), speed_fluctuation=0.0)
        else:
            steady = motor_drive.speed_fluctuation(geometry, mass, loads, setting.motor,
                                                   setting.offset, setting.input_speed)
            theory.update(steady.pair_efforts._asdict(),
                          speed_fluctuation=steady.fluctuation)
    return {name: None if value is None else float(value) for name, value in theory.items()}


# The worker's niceness: its simulations must not take the CPU from the caller's ticks.
WORKER_NICENESS = 10


def _start_worker():
    # Ctrl-C in a terminal reaches the whole process group: the node stops the worker.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.nice(WORKER_NICENESS)


class BackgroundTheory:
    """
    Steady effort theory per setting, worked out in one worker process and kept.

    ``lookup`` never waits: it returns the theory once it is known, else None, and starts the
    work if it is not under way. The worker is spawned (not forked: the caller may hold DDS
    threads) on the first lookup, so a process that never asks pays nothing.
    """

    def __init__(self, limit: int = 64):
        self._limit = limit
        self._known: Dict[tuple, Dict[str, Optional[float]]] = {}
        self._problems: Dict[tuple, str] = {}
        self._pending: Dict[tuple, multiprocessing.pool.AsyncResult] = {}
        self._pool: Optional[multiprocessing.pool.Pool] = None

    def lookup(self, setting: Setting):
        """Return (theory or None, problem or None): None, None while it is being worked out."""
        key = setting.key()
        self._collect()
        if key in self._known:
            return self._known[key], None
        if key in self._problems:
            return None, self._problems[key]
        if key not in self._pending:
            if len(self._known) + len(self._problems) >= self._limit:
                self._known.clear()
                self._problems.clear()
            if self._pool is None:
                self._pool = multiprocessing.get_context('spawn').Pool(
                    1, initializer=_start_worker)
            self._pending[key] = self._pool.apply_async(steady_effort_theory, (setting,))
        return None, None

    def wait(self, setting: Setting, timeout: Optional[float] = None):
        """Start the work if needed and wait for it (for tests and tools, not for ticks)."""
        self.lookup(setting)
        result = self._pending.get(setting.key())
        if result is not None:
            result.wait(timeout)
        return self.lookup(setting)

    def _collect(self):
        for key, result in list(self._pending.items()):
            if not result.ready():
                continue
            del self._pending[key]
            try:
                self._known[key] = result.get()
            except Exception as error:  # noqa: B902 a theory failing must not stop the caller
                self._problems[key] = f'{type(error).__name__}: {error}'

    def close(self):
        """Stop the worker at once, work under way included (a stop must not wait)."""
        if self._pool is not None:
            self._pool.terminate()
            self._pool = None
        self._pending.clear()
