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
Compiled (numba) right-hand side of the motor drive's equation of motion.

dynamics._lean_acceleration_of (the right-hand side's acceleration) and _lean_efforts_of (the
efforts at a stamp), the same functions compiled for floats (their constants as a float64
array): about a quarter of their cost in Python, the same numbers bit for bit (no fast-math
flag, so nothing is fused or reordered; tests hold the forms together).
motor_drive.MotorStepper imports this on a thread of its own and takes it up once loaded
(importing numba and loading the cached machine code take about 0.3 s; the first import
compiles, about 1 s, cached beside this file or in numba's user cache); until then, and
without numba, it runs the Python form. Compiled for its one signature on import, so no
call can start a compilation.
"""

import numba

from qrm_ros.core.dynamics import _lean_acceleration_of, _lean_efforts_of

_ARGUMENTS = '(float64[::1], float64, float64, float64, float64, float64, float64)'
lean_acceleration = numba.njit('float64' + _ARGUMENTS, cache=True,
                               nogil=True)(_lean_acceleration_of)
lean_efforts = numba.njit('UniTuple(float64, 5)' + _ARGUMENTS, cache=True,
                          nogil=True)(_lean_efforts_of)
