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
"""Sums in a written order: left to right, each product rounded, for floats and arrays."""

import numpy as np
import pytest

from qrm_ros.core.numerics.fixed_order import weighted_sum

pytestmark = pytest.mark.bits


def test_terms_are_added_left_to_right():
    # 1 + 1e-16 + 1e-16 is 1 left to right (each addition rounds back to 1), while
    # 1e-16 + 1e-16 + 1 would keep 2e-16 of it: the written order decides.
    assert weighted_sum([1.0, 1e-16, 1e-16], [1.0, 1.0, 1.0]) == 1.0
    assert weighted_sum([1e-16, 1e-16, 1.0], [1.0, 1.0, 1.0]) == 1.0 + 2e-16


def test_each_product_is_rounded_before_it_is_added():
    # x * x - 1 with x = 1 + 2^-30: the product rounded (x*x = 1 + 2^-29 + 2^-60 -> 1 + 2^-29)
    # before the add; a fused multiply-add would keep the 2^-60.
    x = 1.0 + 2.0 ** -30
    assert weighted_sum([x, 1.0], [x, -1.0]) == 2.0 ** -29


def test_arrays_take_the_same_order_element_by_element():
    rng = np.random.default_rng(7)
    terms = rng.standard_normal((5, 100))
    weights = rng.standard_normal(5).tolist()
    got = weighted_sum(terms, weights)
    for column in range(100):
        assert got[column] == weighted_sum(terms[:, column].tolist(), weights)
