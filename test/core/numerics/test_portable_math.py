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
"""The stand-ins for numpy's vector code: the C library's values, numpy's shapes and types."""

import math

import numpy as np
import pytest

from qrm_ros.core.numerics import portable_math, portable_math_kernel

pytestmark = pytest.mark.bits

RNG = np.random.default_rng(20261128)
CASES = [
    (portable_math.arctan2, math.atan2, np.arctan2,
     (RNG.uniform(-2, 2, 2000), RNG.uniform(-2, 2, 2000))),
    (portable_math.arcsin, math.asin, np.arcsin, (RNG.uniform(-1, 1, 2000),)),
    (portable_math.log, math.log, np.log, (RNG.uniform(1e-3, 1e3, 2000),)),
    (portable_math.power, math.pow, np.power,
     (RNG.uniform(1e-3, 10, 2000), RNG.uniform(-8, 8, 2000))),
]


@pytest.mark.parametrize('ours, library, numpy_function, arguments', CASES,
                         ids=lambda case: getattr(case, '__name__', ''))
def test_every_element_is_the_c_librarys_and_within_an_ulp_of_numpys(
        ours, library, numpy_function, arguments):
    got = ours(*arguments)
    assert got.shape == arguments[0].shape and got.dtype == np.float64
    assert got.tolist() == [library(*values) for values in zip(*arguments)]
    # numpy's own vector code (AVX-512) or the same library: an ulp apart at most.
    assert np.all(np.abs(got - numpy_function(*arguments)) <= np.spacing(np.abs(got)))
    scalar = ours(*(float(values[0]) for values in arguments))
    assert type(scalar) is np.float64 and scalar == got[0]
    assert ours(*(values[:1].reshape(()) for values in arguments)) == got[0]


def test_arrays_broadcast_as_numpys():
    bases = np.array([[1.0], [2.0]])
    assert portable_math.power(bases, np.arange(3)).tolist() == [[1.0, 1.0, 1.0],
                                                                 [1.0, 2.0, 4.0]]
    assert portable_math.arctan2(np.ones((2, 3)), 1.0).shape == (2, 3)
    assert portable_math.log(np.array([], dtype=float)).shape == (0,)


def test_where_the_library_refuses_numpys_answer_stands():
    assert portable_math.log(0.0) == -math.inf
    assert math.isnan(portable_math.log(-1.0))
    assert math.isnan(portable_math.arcsin(1.5))
    assert portable_math.power(0.0, -1.0) == math.inf
    assert portable_math.power(1e300, 5.0) == math.inf
    assert portable_math.power(1.01, -math.inf) == 0.0
    values = portable_math.log(np.array([0.0, 1.0, math.inf, math.nan, -2.0]))
    assert values[0] == -math.inf and values[1] == 0.0 and values[2] == math.inf
    assert math.isnan(values[3]) and math.isnan(values[4])


@pytest.mark.parametrize('ours, library, numpy_function, arguments', CASES,
                         ids=lambda case: getattr(case, '__name__', ''))
def test_large_arrays_take_the_compiled_loops_with_the_same_bits(
        ours, library, numpy_function, arguments):
    count = portable_math.COMPILED_MIN_ELEMENTS
    large = tuple(np.resize(values, count) for values in arguments)
    assert not portable_math_kernel.USING_SVML  # so the compiled loops are taken
    got = ours(*large)
    assert got.tolist() == [library(*values) for values in zip(*large)]


def test_large_arrays_refused_by_the_library_give_numpys_answers_too():
    count = portable_math.COMPILED_MIN_ELEMENTS
    values = portable_math.log(np.resize(np.array([0.0, -1.0, math.nan, 1.0]), count))
    assert values[0] == -math.inf and values[3] == 0.0
    nans = values[1::4].tolist() + values[2::4].tolist()
    assert all(np.array(nans).view(np.uint64) == np.array(math.nan).view(np.uint64))
    assert portable_math.power(np.full(count, 1e300), 5.0)[0] == math.inf
    assert math.isnan(portable_math.arcsin(np.full(count, 2.0))[0])
