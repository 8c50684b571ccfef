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
The mechanism's physics, pure numpy/scipy: no ROS, no files, no argparse.

A script needs no map of the modules: ``from qrm_ros.core import Geometry, time_ratio``.
The names listed in ``__init__.pyi`` load with their module on first use (lazy_loader), so
a command that needs one light module (the recorder takes ``core.common.units`` and
``core.kinematics.geometry``) does not load scipy with the rest.

The parts, each importing only from those before it:

* ``common``: names, units and input checks every part shares;
* ``numerics``: arithmetic that gives the same bits on every machine, quadrature, ramps;
* ``kinematics``: the geometry and the exact motion, its stroke times and peak speeds;
* ``dynamics``: masses, loads, efforts, and the ideal speed drive's exact figures;
* ``stepping``: the node's stepper interface, the speed drive and the stroke screw in time;
* ``motor``: the motor drive in time, and its steady running;
* ``measurement`` and ``design``: stroke pairs measured from samples (with what the
  sampling can support), and the tools that choose an offset, a gearbox or a flywheel.
"""

import lazy_loader

# The names of __init__.pyi, each loaded from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
