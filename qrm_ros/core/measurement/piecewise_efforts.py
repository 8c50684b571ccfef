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
Sampled efforts integrated and searched for their peaks piece by piece between load switches.

The ram's load switches at every stroke reversal and, while the tool cuts, where it meets
and leaves the workpiece (doc/dynamics.md); between two switches every effort is a smooth
function of time. Taken as linear across a switch, a jump between two samples costs the
trapezoid rule and the sampled maximum an error of the jump's size: first order in the
sample step. Here the samples are split at the switches found from the recorded motion
(the reversals and the workpiece's edges, both by the stroke finder on the ram's cubic
Hermite interpolant: strokes.workpiece_edge_times), and within each piece every sample
interval is given the polynomial through the samples of the piece nearest to it (six, a
quintic, for the integrals; four, a cubic, for the peaks; a line if the piece has fewer
than six), which also carries the piece to its ends: sixth and fourth order in the step
inside a piece, and a peak at a jump is the piece's one-sided limit there, not the last
sample before it. Pure numpy, and no BLAS: its sums are added in a written order
(core.numerics.fixed_order), so the figures have the same bits on every CPU.
"""

from typing import NamedTuple, Sequence, Tuple, Union

import numpy as np

from qrm_ros.core.numerics.fixed_order import weighted_sum
from qrm_ros.core.numerics.gauss_legendre import gauss_legendre

__all__ = ['INTEGRAL_POINTS', 'MIN_PIECE_SAMPLES', 'PieceIntegrals', 'piecewise_figures',
           'STENCIL_POINTS']

ArrayLike = Union[Sequence[float], np.ndarray]
# Samples each interval's polynomial goes through for the peaks (a cubic: its extremes in
# closed form) and for the integrals (a quintic: two orders more where the samples are
# dense enough to resolve the pieces).
STENCIL_POINTS = 4
INTEGRAL_POINTS = 6
# A piece with fewer samples takes the line through its two nearest samples instead: a
# cubic through a few samples far apart overshoots more than a line.
MIN_PIECE_SAMPLES = 6
# Three-point Gauss-Legendre rule on [0, 1], exact for the quintics integrated.
_RULE_NODES, _RULE_WEIGHTS = gauss_legendre(3)
_GAUSS_NODES = 0.5 * (_RULE_NODES + 1.0)
_GAUSS_WEIGHTS = tuple(0.5 * _RULE_WEIGHTS)
# A cubic on [0, 1] from its values at 0, 1/3, 2/3, 1: the rows give its coefficients
# c0 + c1 u + c2 u^2 + c3 u^3 (the inverse of that Vandermonde matrix, exact in binary).
_THIRDS = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])
_TO_COEFFICIENTS = ((1.0, 0.0, 0.0, 0.0),
                    (-5.5, 9.0, -4.5, 1.0),
                    (9.0, -22.5, 18.0, -4.5),
                    (-4.5, 13.5, -13.5, 4.5))


class PieceIntegrals(NamedTuple):
    """Per stroke pair: the integral of each integrand, the max and min of each signal."""

    integrals: Tuple[np.ndarray, ...]
    highest: Tuple[np.ndarray, ...]
    lowest: Tuple[np.ndarray, ...]
    # True where a piece of the pair holds fewer than MIN_PIECE_SAMPLES samples.
    sparse: np.ndarray


def _stencils(t, switches, left, right, points):
    """
    Each interval [left, right]'s samples: (first sample's index, polynomial degree).

    The interval lies inside one piece (between two switches); its polynomial goes through
    the points samples of that piece nearest to it, centred where the piece allows (a
    line through two, if the piece holds fewer than MIN_PIECE_SAMPLES). A piece holding no
    sample borrows the two samples around the interval.
    """
    middle = 0.5 * (left + right)
    piece = np.searchsorted(switches, middle, side='right')
    sample_piece = np.searchsorted(switches, t, side='right')
    first = np.searchsorted(sample_piece, piece, side='left')
    count = np.searchsorted(sample_piece, piece, side='right') - first
    before = np.searchsorted(t, middle, side='right') - 1  # the sample at or before it
    degree = np.where(count >= max(MIN_PIECE_SAMPLES, points), points,
                      np.minimum(count, 2)) - 1
    start = np.clip(before - (degree - 1) // 2, first, first + count - 1 - degree)
    empty = count == 0
    degree = np.where(empty, 1, degree)
    start = np.where(empty, np.clip(before, 0, t.size - 2), start)
    return start, degree


def _lagrange(nodes, values, degree, points):
    """Evaluate each row's Lagrange polynomial (nodes, values: (m, k)) at points (m, q)."""
    result = np.zeros(points.shape)
    with np.errstate(divide='ignore', invalid='ignore'):
        for j in range(nodes.shape[1]):
            basis = np.ones(points.shape)
            for m in range(nodes.shape[1]):
                if m != j:
                    factor = ((points - nodes[:, m, None])
                              / (nodes[:, j, None] - nodes[:, m, None]))
                    basis = basis * np.where((m <= degree)[:, None], factor, 1.0)
            result += np.where((j <= degree)[:, None], basis * values[:, j, None], 0.0)
    return result


def _cubic_extremes(values_at_thirds):
    """Max and min over [0, 1] of each row's cubic, given by its values at 0, 1/3, 2/3, 1."""
    values = values_at_thirds.T
    c0, c1, c2, c3 = (weighted_sum(values, row) for row in _TO_COEFFICIENTS)
    a, b, c = 3.0 * c3, 2.0 * c2, c1
    with np.errstate(divide='ignore', invalid='ignore'):
        root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
        turns = np.stack([(-b + root) / (2.0 * a), (-b - root) / (2.0 * a), -c / b], axis=1)
    turns[:, :2][np.broadcast_to((a == 0.0)[:, None], (a.size, 2))] = np.nan
    turns[:, 2][a != 0.0] = np.nan
    turns = np.where((turns > 0.0) & (turns < 1.0), turns, 0.0)
    candidates = np.concatenate([values_at_thirds[:, [0, 3]],
                                 ((c3[:, None] * turns + c2[:, None]) * turns
                                  + c1[:, None]) * turns + c0[:, None]], axis=1)
    return np.max(candidates, axis=1), np.min(candidates, axis=1)


def piecewise_figures(time: ArrayLike, switches: ArrayLike, pair_start: ArrayLike,
                      pair_end: ArrayLike, integrands: Sequence[ArrayLike],
                      signals: Sequence[ArrayLike]) -> PieceIntegrals:
    """
    Integrate each integrand and find each signal's max and min over every pair's window.

    time (s, increasing): the samples; switches (s): where the load switches (the pairs'
    ends among them); the windows [pair_start, pair_end] (s) lie between switches. Each
    sample interval inside a piece, and each piece's ends beyond its first and last samples,
    take the polynomial through the piece's nearest samples (module docstring).
    """
    t = np.asarray(time, dtype=float)
    start = np.asarray(pair_start, dtype=float)
    end = np.asarray(pair_end, dtype=float)
    cut = np.unique(np.asarray(switches, dtype=float))
    empty = PieceIntegrals(tuple(np.zeros(start.size) for _ in integrands),
                           tuple(np.full(start.size, -np.inf) for _ in signals),
                           tuple(np.full(start.size, np.inf) for _ in signals),
                           np.ones(start.size, dtype=bool))
    if start.size == 0 or t.size < 2:
        return empty
    low, high = float(np.min(start)), float(np.max(end))
    inside = t[(t > low) & (t < high)]
    points = np.unique(np.concatenate([inside, cut[(cut >= low) & (cut <= high)],
                                       [low, high]]))
    left, right = points[:-1], points[1:]
    middle = 0.5 * (left + right)
    pair = np.searchsorted(start, middle, side='right') - 1
    kept = (pair >= 0) & (middle < end[np.maximum(pair, 0)]) & (right > left)
    left, right, pair = left[kept], right[kept], pair[kept]
    origin = left[:, None]
    width = (right - left)[:, None]
    first, degree = _stencils(t, cut, left, right, INTEGRAL_POINTS)
    index = np.minimum(first[:, None] + np.arange(INTEGRAL_POINTS), t.size - 1)
    nodes = t[index] - origin
    integrals = []
    for integrand in integrands:
        values = np.asarray(integrand, dtype=float)[index]
        at_nodes = _lagrange(nodes, values, degree, width * _GAUSS_NODES)
        piece_integral = width[:, 0] * weighted_sum(at_nodes.T, _GAUSS_WEIGHTS)
        integrals.append(np.bincount(pair, weights=piece_integral, minlength=start.size))
    first, degree = _stencils(t, cut, left, right, STENCIL_POINTS)
    index = np.minimum(first[:, None] + np.arange(STENCIL_POINTS), t.size - 1)
    nodes = t[index] - origin
    highest, lowest = [], []
    for signal in signals:
        values = np.asarray(signal, dtype=float)[index]
        interval_high, interval_low = _cubic_extremes(
            _lagrange(nodes, values, degree, width * _THIRDS))
        pair_high = np.full(start.size, -np.inf)
        pair_low = np.full(start.size, np.inf)
        np.maximum.at(pair_high, pair, interval_high)
        np.minimum.at(pair_low, pair, interval_low)
        highest.append(pair_high)
        lowest.append(pair_low)
    pieces = cut[(cut >= low) & (cut <= high)]
    counts = np.diff(np.searchsorted(t, pieces, side='right'))
    centre = 0.5 * (pieces[:-1] + pieces[1:])
    owner = np.searchsorted(start, centre, side='right') - 1
    sparse = np.zeros(start.size, dtype=bool)
    few = ((counts < MIN_PIECE_SAMPLES) & (owner >= 0)
           & (centre < end[np.maximum(owner, 0)]))
    sparse[owner[few]] = True
    return PieceIntegrals(tuple(integrals), tuple(highest), tuple(lowest), sparse)
