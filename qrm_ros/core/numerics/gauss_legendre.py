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
Gauss-Legendre rules as constants: correctly rounded, the same bits on every machine.

scipy's roots_legendre and numpy's leggauss find the nodes by an eigensolver and the
weights with numpy's vector functions, so their last bits follow the CPU's LAPACK kernels
and numpy's choice of vector code (some orders' weights change with AVX-512), and they
are up to a few hundred ulps from the true values. The rules the core uses are written
here once, each node and weight the double nearest the true value (worked out to 60 digits;
test/core/numerics/test_gauss_legendre.py works them out again with mpmath). Nodes on [-1, 1] are
symmetric: the table holds those >= 0 and their weights.
"""

from typing import Dict, Tuple

import numpy as np

__all__ = ['gauss_legendre', 'ORDERS']

_HALF_RULES: Dict[int, Tuple[Tuple[str, ...], Tuple[str, ...]]] = {
    3: (('0x0.0p+0', '0x1.8c97ef43f7248p-1'),
        ('0x1.c71c71c71c71cp-1', '0x1.1c71c71c71c72p-1')),
    8: (('0x1.77ac94f3c7345p-3', '0x1.0d129583284b4p-1', '0x1.97e4ab249f41ep-1',
         '0x1.ebab1cb0acc67p-1'),
        ('0x1.736360b199343p-2', '0x1.413c50a255615p-2', '0x1.c76fb531d2b96p-3',
         '0x1.9ea1d04ca0374p-4')),
    20: (('0x1.3973df98b86b0p-4', '0x1.d281636928bc0p-3', '0x1.7eaccf15652c4p-2',
          '0x1.05905c13f7ff7p-1', '0x1.45a8d3fa710dbp-1', '0x1.7e1f37346a54ep-1',
          '0x1.ada0bd5efd6e7p-1', '0x1.d31064173fd92p-1', '0x1.ed8dba7bd769fp-1',
          '0x1.fc7b5a0c71ce0p-1'),
         ('0x1.38d6c490a3370p-3', '0x1.31819b52c5992p-3', '0x1.230348f34a535p-3',
          '0x1.0db2c5db26dffp-3', '0x1.e41ff31573b48p-4', '0x1.a1817a317a821p-4',
          '0x1.5519fe196e24ap-4', '0x1.00b467df7e475p-4', '0x1.4c9b5ea53b67fp-5',
          '0x1.209680274e8afp-6')),
}
ORDERS = tuple(sorted(_HALF_RULES))


def gauss_legendre(order: int) -> Tuple[np.ndarray, np.ndarray]:
    """Return the order-point rule on [-1, 1]: (nodes ascending, weights), read-only."""
    try:
        half_nodes, half_weights = _HALF_RULES[order]
    except KeyError:
        raise ValueError(f'no Gauss-Legendre rule of order {order}: orders {ORDERS}') from None
    positive = [float.fromhex(node) for node in half_nodes]
    weights = [float.fromhex(weight) for weight in half_weights]
    middle = 1 if positive[0] == 0.0 else 0  # an odd order's node 0 is not mirrored
    nodes = np.array([-node for node in reversed(positive[middle:])] + positive)
    weights_all = np.array(list(reversed(weights[middle:])) + weights)
    nodes.flags.writeable = weights_all.flags.writeable = False
    return nodes, weights_all
