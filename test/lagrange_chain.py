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
"""The mechanism's Lagrangian in sympy, written from the positions alone: a test helper.

The independent derivation the efforts and the motor's equation of motion are checked
against (test/core): phi(theta, offset) and psi(phi, r) from doc/mechanism.md, x = H tan(psi),
T and V as doc/dynamics.md, for the coordinates q = (theta, offset, r).
"""

from typing import Any, List, NamedTuple

import sympy

from qrm_ros.core.dynamics import chain as dyn


class ChainLagrangian(NamedTuple):
    coordinates: Any     # (theta, delta, r)
    rates: Any           # their first derivatives
    accelerations: Any   # their second derivatives
    ram_force: Any       # F, the external force on the ram along x
    ram_position: Any    # x(q)
    lagrangian: Any      # T - V


def chain_lagrangian(mass: dyn.MassProperties, coupling_radius: float, pivot_distance: float,
                     ram_height: float) -> ChainLagrangian:
    """Return the mechanism's Lagrangian and its symbols."""
    q = sympy.symbols('theta delta r', real=True)
    qd = sympy.symbols('theta_d delta_d r_d', real=True)
    qdd = sympy.symbols('theta_dd delta_dd r_dd', real=True)
    force = sympy.Symbol('F', real=True)
    theta, delta, radius = q
    phi = theta + sympy.atan2(delta * sympy.cos(theta),
                              coupling_radius + delta * sympy.sin(theta))
    psi = sympy.atan2(radius * sympy.cos(phi), pivot_distance + radius * sympy.sin(phi))
    x = ram_height * sympy.tan(psi)

    def rate(expression):
        return sum(sympy.diff(expression, qi) * qdi for qi, qdi in zip(q, qd))
    kinetic = (mass.input_inertia * qd[0] ** 2 + mass.flywheel_inertia * rate(phi) ** 2
               + mass.lever_inertia * rate(psi) ** 2 + mass.ram_mass * rate(x) ** 2) / 2
    potential = mass.lever_mass * mass.gravity * mass.lever_com_distance * sympy.cos(psi)
    return ChainLagrangian(q, qd, qdd, force, x, kinetic - potential)


def generalised_forces(chain: ChainLagrangian, indices=(0, 1, 2)) -> List[Any]:
    """Q_i = d/dt dL/dq_i' - dL/dq_i - F dx/dq_i for each coordinate index asked for."""
    q, qd, qdd = chain.coordinates, chain.rates, chain.accelerations
    forces = []
    for index in indices:
        momentum = sympy.diff(chain.lagrangian, qd[index])
        momentum_rate = sum(sympy.diff(momentum, qj) * qdj + sympy.diff(momentum, qdj) * qddj
                            for qj, qdj, qddj in zip(q, qd, qdd))
        forces.append(momentum_rate - sympy.diff(chain.lagrangian, q[index])
                      - chain.ram_force * sympy.diff(chain.ram_position, q[index]))
    return forces
