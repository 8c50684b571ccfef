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
The tests that compare bits (``-m bits``) again, in fresh interpreters under other kernels.

OpenBLAS, numpy and numba pick their code by the CPU when they load, so each setting needs
a process of its own (doc/reproducibility.md):

- other kernels: an OpenBLAS kernel other than this machine's (Prescott's SSE code, or
  Haswell's where this machine already takes Prescott's), numpy's AVX2 and AVX-512 code off,
  numba compiling for a generic x86-64. The results are promised bit for bit across these,
  so the bit tests compare exactly, as they do here;
- glibc's code for CPUs without FMA (GLIBC_TUNABLES hides AVX2 and FMA): the C library's
  functions may then differ in the last bit, so reference_math() is false there and the bit
  tests compare within the bounds the contract states.

So a change that brings a machine dependence back fails on any machine, this one included.
"""

import ast
import glob
import os
import re
import subprocess
import sys

import pytest

from qrm_ros.testing import reference_math
from repo_paths import REPO_ROOT

# numpy's dispatched code above its x86-64-v2 baseline (numpy 2.4's names).
NUMPY_FEATURES_OFF = 'X86_V3 X86_V4 AVX512_ICL'
GLIBC_WITHOUT_FMA = 'glibc.cpu.hwcaps=-AVX2,-FMA'
# What a child prints of the OpenBLAS kernel it loaded (numpy's bundled OpenBLAS).
CORE_NAME = '''
import ctypes, numpy
path = next(line.split()[-1] for line in open('/proc/self/maps') if 'openblas' in line)
name = ctypes.CDLL(path).scipy_openblas_get_corename64_
name.restype = ctypes.c_char_p
print(name().decode())
'''
TIMEOUT = 900.0
# What numpy and scipy work out with code picked by the CPU: BLAS (products, norms,
# solvers), numpy's vector code for the inverse and exponential functions, eigensolvers.
# The promised paths take core.numerics.fixed_order, core.numerics.portable_math,
# core.numerics.gauss_legendre instead.
MACHINE_PICKED = {'dot', 'vdot', 'inner', 'matmul', 'einsum', 'tensordot', 'vander', 'polyfit',
                  'arctan2', 'arcsin', 'arccos', 'arctan', 'tan', 'exp', 'exp2', 'expm1', 'log',
                  'log1p', 'log2', 'log10', 'power', 'float_power', 'sinh', 'cosh', 'tanh',
                  'arcsinh', 'arccosh', 'arctanh', 'cbrt', 'roots_legendre', 'leggauss',
                  'solve_ivp'}
MACHINE_PICKED_OWNERS = ('np', 'numpy', 'special', 'scipy', 'integrate', 'linalg')
# Modules that may: what they work out is drawn, not promised.
MAY_PICK = {os.path.join('qrm_ros', 'analysis', 'figures.py'): "a figure's geometry"}


def _machine_picked_calls(path):
    """Yield (line, what) of every call of MACHINE_PICKED (and every @) in a module."""
    with open(path) as stream:
        tree = ast.parse(stream.read())
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            yield node.lineno, '@'
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner = ast.unparse(node.func.value)
            if ('linalg' in owner.split('.') or node.func.attr in MACHINE_PICKED
                    and owner.split('.')[0] in MACHINE_PICKED_OWNERS):
                yield node.lineno, f'{owner}.{node.func.attr}'


def test_the_package_calls_no_math_the_machine_picks():
    modules = sorted(os.path.relpath(path, REPO_ROOT) for path in glob.glob(
        os.path.join(REPO_ROOT, 'qrm_ros', '**', '*.py'), recursive=True))
    assert len(modules) > 100
    found = [f'{path}:{line}: {what}' for path in modules if path not in MAY_PICK
             for line, what in _machine_picked_calls(os.path.join(REPO_ROOT, path))]
    assert not found, '\n'.join(found)
    assert all(any(True for _ in _machine_picked_calls(os.path.join(REPO_ROOT, path)))
               for path in MAY_PICK)  # still needed


def _openblas_core(environment):
    done = subprocess.run([sys.executable, '-c', CORE_NAME], env=environment,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def _environment(**changes):
    environment = dict(os.environ)
    environment.update(changes)
    return environment


def _other_kernels():
    host = _openblas_core(os.environ)
    other = 'Haswell' if host in ('Katmai', 'Prescott') else 'Prescott'
    environment = _environment(OPENBLAS_CORETYPE=other,
                               NPY_DISABLE_CPU_FEATURES=NUMPY_FEATURES_OFF,
                               NUMBA_CPU_NAME='generic')
    assert _openblas_core(environment) != host  # the setting took
    return environment


def _run_bit_tests(environment):
    done = subprocess.run(
        [sys.executable, '-m', 'pytest', '-m', 'bits', '-q', '-p', 'no:cacheprovider',
         os.path.join(REPO_ROOT, 'test')],
        cwd=REPO_ROOT, env=environment, capture_output=True, text=True, timeout=TIMEOUT)
    tail = '\n'.join(done.stdout.splitlines()[-30:])
    assert done.returncode == 0, tail + done.stderr[-2000:]
    passed = re.search(r'(\d+) passed', done.stdout)
    assert passed and int(passed.group(1)) >= 100, tail
    return done.stdout


@pytest.mark.skipif(not reference_math(), reason='the bit tests compare exactly only on the '
                    'reference machines; here they already run within their bounds')
def test_the_bit_tests_pass_exactly_under_other_kernels():
    _run_bit_tests(_other_kernels())


@pytest.mark.skipif(not reference_math(), reason='needs a glibc whose FMA code can be hidden')
def test_the_bit_tests_hold_their_bounds_with_glibcs_code_for_cpus_without_fma():
    environment = _environment(GLIBC_TUNABLES=GLIBC_WITHOUT_FMA)
    check = subprocess.run(
        [sys.executable, '-c', 'from qrm_ros.testing import reference_math; '
         'print(reference_math())'], env=environment, capture_output=True, text=True,
        cwd=REPO_ROOT, timeout=60)
    assert check.stdout.strip() == 'False', check.stderr
    _run_bit_tests(environment)
