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
Whether this machine computes as the one the shipped runs were made on, to the last bit.

The package's results are the same bits on every machine of one kind (doc/reproducibility.md):
Linux on x86-64 with the glibc release the example runs and golden logs were made with, on a
CPU with AVX2 and FMA, by which glibc picks the code of its sines, exponentials and logarithms.
Elsewhere those may differ in the last bit, and a test compares within a bound instead.
"""

import os
import platform
import sys
from typing import FrozenSet, Mapping, Optional

__all__ = ['OTHER_MACHINE_RELATIVE', 'REFERENCE_GLIBC', 'reference_math']

# The glibc release of the machine that made the shipped runs (Debian 12).
REFERENCE_GLIBC = '2.36'
# Elsewhere, how far a replayed or simulated joint value may be from the shipped one, relative
# to the largest of its kind in the run: the motor drive's integration carries the C
# library's last bits on (measured: 4e-11 over the 4 s example, 4e-10 over 30 s of cutting;
# the speed drive's closed forms move by a few ulps). doc/reproducibility.md.
OTHER_MACHINE_RELATIVE = 1e-9
# The CPU features glibc's libm picks its code by; GLIBC_TUNABLES can hide them.
LIBM_FEATURES = frozenset({'avx2', 'fma'})
# Names GLIBC_TUNABLES' glibc.cpu.hwcaps takes for them (AVX2 needs AVX), old and new.
_HIDING = frozenset({'-AVX', '-AVX2', '-FMA', '-AVX_Usable', '-AVX2_Usable', '-FMA_Usable'})


def _cpu_flags() -> FrozenSet[str]:
    """Return the CPU's feature flags as Linux lists them (none if it cannot say)."""
    try:
        with open('/proc/cpuinfo') as stream:
            for line in stream:
                if line.startswith('flags'):
                    return frozenset(line.split(':', 1)[1].split())
    except OSError:
        pass
    return frozenset()


def _libm_features_hidden(environment: Mapping[str, str]) -> bool:
    """Whether GLIBC_TUNABLES hides AVX, AVX2 or FMA from glibc (its other libm code then)."""
    for tunable in environment.get('GLIBC_TUNABLES', '').split(':'):
        name, _, value = tunable.partition('=')
        if name.strip() == 'glibc.cpu.hwcaps' and _HIDING & {
                part.strip() for part in value.split(',')}:
            return True
    return False


def reference_math(environment: Optional[Mapping[str, str]] = None) -> bool:
    """
    Return whether results here are promised bit for bit equal to the shipped runs'.

    True on Linux x86-64 with glibc REFERENCE_GLIBC and a CPU whose AVX2 and FMA glibc uses;
    whatever OpenBLAS kernel, numpy vector code or numba target the machine picks.
    environment: the process environment to judge (default os.environ).
    """
    if sys.platform != 'linux' or platform.machine() != 'x86_64':
        return False
    if platform.libc_ver() != ('glibc', REFERENCE_GLIBC):
        return False
    return (LIBM_FEATURES <= _cpu_flags()
            and not _libm_features_hidden(os.environ if environment is None else environment))
