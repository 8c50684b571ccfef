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
Compiled (numba): the motor drive's equation of motion and the speed drive's sample.

lean_chain.lean_acceleration_of (the right-hand side's acceleration) and lean_efforts_of (the
efforts at a stamp), and lean_speed_drive_sample (the speed drive's tick at a still stroke,
core.stepping.speed_drive_sample), the same functions compiled for floats (their constants as a
float64 array): about a quarter of their cost in Python, the same numbers bit for bit (no fast-math
flag, so nothing is fused or reordered; tests hold the forms together). The head they share,
lean_coefficients (and its own head, coupling_and_crank), is registered as callable from
compiled code and compiled into all three.
drive_kernel_loading imports this on a thread of its own and the MotorStepper (and the speed
drive's sample) takes it up once loaded (importing numba and loading the cached machine code
take about 0.3 s; the first import compiles, about 1 s, cached beside this file or in numba's
user cache); until then, and without numba, it runs the Python form. Compiled for its one
signature on import, so no call can start a compilation.
"""

import numba
from numba.extending import register_jitable

from qrm_ros.core.dynamics.chain import one_sample_ram_load
from qrm_ros.core.dynamics.lean_chain import (coupling_and_crank, lean_acceleration_of,
                                              lean_coefficients, lean_efforts_of,
                                              lean_speed_drive_sample, lever_radius_coefficient_of,
                                              SPEED_DRIVE_SAMPLE_FIELDS)

register_jitable(coupling_and_crank)
register_jitable(lean_coefficients)
# Called within lean_speed_drive_sample:
register_jitable(lean_efforts_of)
register_jitable(lever_radius_coefficient_of)
register_jitable(one_sample_ram_load)

_ARGUMENTS = '(float64[::1], float64, float64, float64, float64, float64, float64)'
lean_acceleration = numba.njit('float64' + _ARGUMENTS, cache=True,
                               nogil=True)(lean_acceleration_of)
lean_efforts = numba.njit('UniTuple(float64, 5)' + _ARGUMENTS, cache=True,
                          nogil=True)(lean_efforts_of)
# The speed drive's sample at a still stroke (core.stepping.speed_drive_sample): the constants,
# three load fields and five of the state.
lean_speed_drive = numba.njit(
    f'UniTuple(float64, {len(SPEED_DRIVE_SAMPLE_FIELDS)})(float64[::1]{", float64" * 8})',
    cache=True)(lean_speed_drive_sample)  # holds the GIL: releasing it cost more than the call
