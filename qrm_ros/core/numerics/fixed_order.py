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
Sums of products in a written order: the same bits on every CPU.

numpy hands matrix and dot products and vector norms to BLAS, and OpenBLAS picks its kernel
by the CPU it runs on (with or without fused multiply-adds, the terms summed in another
order), so their last bits depend on the machine. The paths whose bits the docs promise
(doc/reproducibility.md) add their terms here instead: left to right, each product rounded
before it is added, in plain IEEE arithmetic. Pure Python: floats and numpy arrays alike.
"""

from typing import Any, Sequence

__all__ = ['weighted_sum']


def weighted_sum(terms: Sequence[Any], weights: Sequence[float]) -> Any:
    """Return terms[0] * weights[0] + terms[1] * weights[1] + ..., added left to right."""
    total = terms[0] * weights[0]
    for index in range(1, len(weights)):
        total = total + terms[index] * weights[index]
    return total
