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
Dynamics of the mechanism: masses, loads, efforts and inertia, and the ideal speed drive.

``from qrm_ros.core import dynamics as dyn`` reaches the chain's public names (``dyn.Loads``,
``dyn.efforts``; ``__init__.pyi``, loaded on first use). The modules: chain (the efforts
through the velocity coefficients, on arrays or floats), lean_chain (the same on plain floats,
for the motor's equation of motion), physical_ranges (bounds no shaper leaves), stroke_efforts
(while the stroke screw moves), speed_drive (the ideal speed drive's exact figures),
torque_kernel, drive_kernel and drive_kernel_loading (their compiled forms).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
