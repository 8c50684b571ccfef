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
The one list of what qrm_ros.core.dynamics exports, and from where.

lazy_loader reads it at run time (each name loads with its module on first use); type
checkers read it as the package's interface (``name as name``: a stub's import re-exports
only in that form).
"""

from .chain import (checked_quantity as checked_quantity, DynamicsError as DynamicsError,
                    Efforts as Efforts, efforts as efforts,
                    generalized_inertia as generalized_inertia, Loads as Loads,
                    MassProperties as MassProperties, MotorDrive as MotorDrive,
                    one_sample_ram_load as one_sample_ram_load, ram_load_force as ram_load_force)
