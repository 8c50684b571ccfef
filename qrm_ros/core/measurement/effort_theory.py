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
drive's exact figures (speed_drive.pair_efforts) or the motor drive's steady running
(steady_running.speed_fluctuation). The motor drive's answer takes a simulation of many
revolutions, far longer than a node's tick, so ``BackgroundTheory`` works it out in a
worker process and the node picks it up once it is there: no tick waits for it.
"""

import contextlib
import math
import os
import pickle
import queue
import signal
import subprocess
import sys
import threading
import time
from typing import BinaryIO, Dict, NamedTuple, Optional, Tuple

from qrm_ros.core.dynamics import chain as dyn
from qrm_ros.core import kinematics as kin
from qrm_ros.core.dynamics.speed_drive import pair_efforts, ToleranceUnreachable
from qrm_ros.core.motor.steady_running import speed_fluctuation

__all__ = ['BackgroundTheory', 'EFFORT_FIGURES', 'Setting', 'steady_effort_theory',
           'steady_effort_theory_and_problem', 'THEORY_FIGURES', 'ZERO_CAN_BE_EXACT']

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

    def key(self) -> tuple:
        """Return the setting's values, hashable (the parameter sets compare by identity)."""
        def values(part):
            return None if part is None else tuple(sorted(part.as_dict().items()))
        geometry = tuple(getattr(self.geometry, name) for name in kin.Geometry.field_names())
        return (geometry, values(self.mass), values(self.loads), values(self.motor),
                float(self.offset), float(self.input_speed))


def steady_effort_theory(setting: Setting) -> Dict[str, Optional[float]]:
    """Return the drive's figures of one pair (steady_effort_theory_and_problem's first)."""
    return steady_effort_theory_and_problem(setting)[0]


def steady_effort_theory_and_problem(
        setting: Setting) -> Tuple[Dict[str, Optional[float]], Optional[str]]:
    """
    Return the drive's figures of one pair at a steady setting, name -> value.

    None where there is no theory: a stopped shaft, a setting the core refuses (an offset at
    the coupling radius, a speed too large to be finite) or a motor that stalls. The problem
    (str) says when the theory exists but cannot be worked out to its tolerance within its
    bounded cost (near the coupling radius): the figures are then missing, not absent.
    """
    theory: Dict[str, Optional[float]] = dict.fromkeys(THEORY_FIGURES)
    if setting.input_speed == 0.0:
        return theory, None
    problem = None
    geometry, mass, loads = setting.geometry, setting.mass, setting.loads
    try:
        if setting.motor is None:  # the ideal speed drive holds the speed: no fluctuation
            figures = pair_efforts(geometry, mass, loads, setting.offset, setting.input_speed)
            if (loads.cutting_force == 0.0 and loads.ram_friction == 0.0
                    and abs(figures.energy_per_pair)
                    <= _ROUNDOFF * 2 * math.pi * figures.rms_input_torque):
                figures = figures._replace(energy_per_pair=0.0, mean_input_power=0.0)
            theory.update(figures._asdict(), speed_fluctuation=0.0)
        else:
            steady = speed_fluctuation(geometry, mass, loads, setting.motor, setting.offset,
                                       setting.input_speed)
            theory.update(steady.pair_efforts._asdict(),
                          speed_fluctuation=steady.fluctuation)
    except ToleranceUnreachable as error:
        problem = str(error)
    except kin.KinematicsError:
        pass
    return ({name: None if value is None else float(value) for name, value in theory.items()},
            problem)


# A lookup's answer: (theory or None, problem or None).
Answer = Tuple[Optional[Dict[str, Optional[float]]], Optional[str]]
# The worker's niceness: its simulations must not take the CPU from the caller's ticks.
WORKER_NICENESS = 10


def _answer(key, setting):
    """Return the worker's reply to one request: (key, theory or None, problem or None)."""
    try:
        return key, steady_effort_theory(setting), None
    except Exception as error:  # noqa: B902 a theory failing must not stop the worker
        return key, None, f'{type(error).__name__}: {error}'


def serve(requests: BinaryIO, replies: BinaryIO) -> None:
    """Answer pickled (key, Setting) requests with pickled replies until the input ends."""
    while True:
        try:
            key, setting = pickle.load(requests)
        except EOFError:  # the caller closed the pipe, or died
            return
        pickle.dump(_answer(key, setting), replies)
        replies.flush()


class BackgroundTheory:
    """
    Steady effort theory per setting, worked out in one worker process and kept.

    ``lookup`` never waits: it returns the theory once it is known, else None, and starts the
    work if it is not under way. The worker is a fresh interpreter running this module
    (``python -m qrm_ros.core.measurement.effort_theory``), started on the first lookup, at low
    priority and in a session of its own (a terminal's Ctrl-C is the caller's to handle): not a
    fork of a process that may hold DDS threads, and not multiprocessing's spawn, which would run
    the caller's main script again in the worker. Requests and replies are pickled over its
    standard input and output; a thread reads the replies. It ends when the caller closes
    the pipe (close(), or the caller's exit, however it happens).
    """

    def __init__(self, limit: int = 64) -> None:
        self._limit = limit
        self._known: Dict[tuple, Dict[str, Optional[float]]] = {}
        self._problems: Dict[tuple, str] = {}
        self._pending: set = set()
        self._replies: queue.Queue = queue.Queue()
        self._worker: Optional[subprocess.Popen] = None

    def lookup(self, setting: Setting) -> Answer:
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
            self._ask(key, setting)
        return None, None

    def wait(self, setting: Setting, timeout: float = 60.0) -> Answer:
        """Start the work if needed and wait for it (for tests and tools, not for ticks)."""
        deadline = time.monotonic() + timeout
        answer = self.lookup(setting)
        while answer == (None, None) and time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                self._keep(self._replies.get(timeout=max(0.0, deadline - time.monotonic())))
            answer = self.lookup(setting)
        return answer

    def work_out(self, setting: Setting) -> Answer:
        """
        Return (theory or None, problem or None), worked out here and now if not known.

        For a caller that would wait for the worker anyway (an offline run): the same
        function the worker runs, without a worker to start.
        """
        key = setting.key()
        self._collect()
        if key not in self._known and key not in self._problems:
            if len(self._known) + len(self._problems) >= self._limit:
                self._known.clear()
                self._problems.clear()
            self._keep(_answer(key, setting))
        return self._known.get(key), self._problems.get(key)

    def _ask(self, key, setting):
        if self._worker is None or self._worker.poll() is not None:
            environment = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
            self._worker = subprocess.Popen(
                [sys.executable, '-m', __name__], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, env=environment, start_new_session=True)
            threading.Thread(target=self._read, args=(self._worker,), daemon=True).start()
            self._pending.clear()  # asked of a worker that is gone: asked again when looked up
        try:
            pickle.dump((key, setting), self._worker.stdin)
            self._worker.stdin.flush()
            self._pending.add(key)
        except OSError as error:  # the worker is gone: say so for this setting
            self._problems[key] = f'the theory worker is gone: {error}'

    def _read(self, worker):
        """Queue the worker's replies until it ends (a thread of its own, owning the pipe)."""
        with worker.stdout:
            while True:
                try:
                    self._replies.put(pickle.load(worker.stdout))
                except (EOFError, OSError, pickle.UnpicklingError):
                    return

    def _keep(self, reply):
        key, theory, problem = reply
        self._pending.discard(key)
        if theory is not None:
            self._known[key] = theory
        else:
            self._problems[key] = problem

    def _collect(self):
        while True:
            try:
                self._keep(self._replies.get_nowait())
            except queue.Empty:
                return

    @property
    def worker_pid(self) -> Optional[int]:
        """The worker process's id while it runs (its priority is the caller's to check)."""
        worker = self._worker
        return worker.pid if worker is not None and worker.poll() is None else None

    def close(self) -> None:
        """Stop the worker at once, work under way included (a stop must not wait)."""
        if self._worker is not None:
            self._worker.kill()
            self._worker.wait()  # its replies' pipe ends too: the reading thread closes it
            with contextlib.suppress(OSError):
                self._worker.stdin.close()  # type: ignore[union-attr]  # made a PIPE
            self._worker = None
        self._pending.clear()


if __name__ == '__main__':
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller stops the worker
    os.nice(WORKER_NICENESS)
    replies = os.fdopen(os.dup(sys.stdout.fileno()), 'wb')
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # a stray print must not corrupt them
    serve(sys.stdin.buffer, replies)
