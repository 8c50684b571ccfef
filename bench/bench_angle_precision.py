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
Long-run precision of the node's input angle, against exact decimal arithmetic.

    python3 dev.py run python bench/bench_angle_precision.py [--revolutions 1e6]

ShaperStepper keeps the input angle wrapped to [-pi, pi) and removes whole turns with 2 pi
split into a double and its remainder. This steps it at 1000 rad/s with 1 kHz stamps and
compares the angle with the exact one (speed x time mod 2 pi, in 60-digit decimals), with
the two-part 2 pi and with the plain double 2 pi, and prints the error per revolution.
"""

import argparse
from decimal import Decimal, getcontext
import math

from qrm_ros.core.stepping import stepping
from qrm_ros.core.kinematics.geometry import Geometry

getcontext().prec = 60
PI = Decimal('3.14159265358979323846264338327950288419716939937510582097494459')
SPEED = 1000.0  # rad/s
RATE_NS = 1_000_000  # 1 kHz


def exact_angle(stamp_ns):
    turns = Decimal(SPEED) * Decimal(stamp_ns) / Decimal(10**9)
    wrapped = (turns + PI) % (2 * PI) - PI
    return wrapped


def run(ticks, low_part):
    saved = stepping._TWO_PI_LOW
    stepping._TWO_PI_LOW = saved if low_part else 0.0
    try:
        stepper = stepping.ShaperStepper(Geometry.paper(), SPEED, 0.0, 1e5, 1.0)
        stepper.integrate_to(0)
        # Stamps jump ahead by whole seconds (1000 rad, many turns) then tick at 1 kHz: the
        # per-tick wrap is what the node does; the jumps reach many revolutions quickly.
        stamp = 0
        for _ in range(ticks):
            stamp += RATE_NS
            stepper.integrate_to(stamp)
        error = float(Decimal(stepper.input_angle) - exact_angle(stamp))
        return abs(math.remainder(error, 2 * math.pi)), SPEED * stamp / 1e9 / (2 * math.pi)
    finally:
        stepping._TWO_PI_LOW = saved


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--ticks', type=float, default=2e6, help='1 kHz ticks to step')
    args = parser.parse_args()
    for low_part in (True, False):
        error, revolutions = run(int(args.ticks), low_part)
        name = 'two-part 2 pi' if low_part else 'double 2 pi  '
        print(f'{name}: after {revolutions:.4g} revolutions the input angle is off by '
              f'{error:.3g} rad, {error / revolutions:.3g} rad per revolution')


if __name__ == '__main__':
    main()
