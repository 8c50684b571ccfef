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
"""The Gauss-Legendre constants: each the double nearest the true node or weight."""

import mpmath
import numpy as np
import pytest

from qrm_ros.core.numerics.gauss_legendre import gauss_legendre, ORDERS

pytestmark = pytest.mark.bits

DIGITS = 60


def _legendre_and_slope(order, x):
    """P_n(x) and P_n'(x) by the three-term recurrence, in mpmath."""
    before, now = mpmath.mpf(1), x
    for k in range(2, order + 1):
        before, now = now, ((2 * k - 1) * x * now - (k - 1) * before) / k
    return now, order * (x * now - before) / (x * x - 1)


def _true_rule(order):
    """Nodes (ascending) and weights to DIGITS digits: Newton from the usual guesses."""
    with mpmath.workdps(DIGITS):
        nodes, weights = [], []
        for i in range(1, order + 1):
            x = mpmath.cos(mpmath.pi * (i - mpmath.mpf('0.25')) / (order + mpmath.mpf('0.5')))
            for _ in range(100):
                value, slope = _legendre_and_slope(order, x)
                x -= value / slope
                if abs(value / slope) < mpmath.mpf(10) ** (5 - DIGITS):
                    break
            _, slope = _legendre_and_slope(order, x)
            nodes.append(x)
            weights.append(2 / ((1 - x * x) * slope * slope))
        ranked = sorted(range(order), key=lambda k: nodes[k])
        return [nodes[k] for k in ranked], [weights[k] for k in ranked]


@pytest.mark.parametrize('order', ORDERS)
def test_every_node_and_weight_is_the_nearest_double(order):
    nodes, weights = gauss_legendre(order)
    true_nodes, true_weights = _true_rule(order)
    # mpmath rounds to nearest when it makes a float of a 60-digit value.
    assert nodes.tolist() == [float(x) for x in true_nodes]
    assert weights.tolist() == [float(w) for w in true_weights]
    assert len(set(nodes.tolist())) == order


@pytest.mark.parametrize('order', ORDERS)
def test_the_rule_integrates_polynomials_to_its_degree(order):
    nodes, weights = gauss_legendre(order)
    for degree in range(2 * order):
        exact = 0.0 if degree % 2 else 2.0 / (degree + 1)
        assert abs(float(np.sum(weights * nodes ** degree)) - exact) < 1e-14


def test_the_rules_are_read_only_and_unknown_orders_refused():
    nodes, weights = gauss_legendre(8)
    with pytest.raises(ValueError):
        nodes[0] = 0.0
    with pytest.raises(ValueError, match='no Gauss-Legendre rule of order 5: orders'):
        gauss_legendre(5)
