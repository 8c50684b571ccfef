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
"""The motor stepper's solver: its dense output in plain floats is scipy's bit for bit."""

import math

import numpy as np
import pytest
from scipy import integrate

from qrm_ros.core.motor.motor_integration import ATOL, float_dense, RTOL

pytestmark = pytest.mark.bits


def _bits(values):
    return [float(value).hex() for value in values]


def test_the_float_dense_output_is_scipys_bit_for_bit():
    solver = integrate.DOP853(lambda time, y: [y[1], -9.0 * math.sin(y[0]) - 0.1 * y[1]],
                              0.0, [0.3, 2.0], 20.0, rtol=RTOL, atol=ATOL)
    for _ in range(30):
        solver.step()
        dense = solver.dense_output()
        at = float_dense(dense)
        times = np.linspace(solver.t_old, solver.t, 17).tolist()
        for time, expected in zip(times, dense(times).T):
            assert _bits(at(time)) == _bits(expected) == _bits(dense(time))
