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
Exact kinematics of the modified quick-return mechanism: the core's part that knows the motion.

The chain is input shaft -> offset yoke coupling -> flywheel -> crank pin -> slotted lever
-> ram (doc/mechanism.md). Each question has a module of its own, and the package names
their answers (``__init__.pyi``, each loaded on first use), so ``from qrm_ros.core import
kinematics as kin`` reaches every one:

* the drive's dimensions and the offset's range: geometry;
* every joint's exact state, the coupling's inverse, the reversals: mechanism_state;
* stroke times, time ratio and mid-stroke speed ratio: stroke_timing;
* the largest ram speeds of each stroke: peak_speeds (its sign test in speed_rise, compiled
  for large sweeps in peak_kernel; the previous method, kept as the tests' reference, in
  peak_speeds_bracketing);
* every figure of steady running at once: steady_figures;
* the offset for a wanted ratio or peak cutting speed: offset_inverses;
* the mean cutting speed and its inverse: cutting_speeds;
* where each pin and link is, for drawing: linkage.

For a positive input speed the slow stroke, which moves the ram toward -x (ram velocity
< 0), is the cutting stroke; running in reverse makes the cut the fast stroke (TR < 1).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
