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
The names load on first use (PEP 562), so a command that needs one light module (the
recorder takes ``core.units`` and ``core.geometry``) does not load scipy with the rest. The
imports under ``TYPE_CHECKING`` below are the one list of what is exported and from where:
type checkers read them, and ``core.exports`` reads the same lines from this file's source.
"""

from typing import TYPE_CHECKING

from qrm_ros.core.exports import declared_exports, lazy_attributes

if TYPE_CHECKING:
    from qrm_ros.core.cutting_speed_hold import (cutting_speed, hold_offset, HoldAnswer,
                                                 reachable_cutting_speeds)
    from qrm_ros.core.cutting_speeds import mean_cutting_speed, offset_for_mean_cutting_speed
    from qrm_ros.core.dynamics import (DynamicsError, Efforts, efforts, generalized_inertia,
                                       Loads, MassProperties, MotorDrive, ram_load_force)
    from qrm_ros.core.flywheel_design import FlywheelSizing, size_flywheel
    from qrm_ros.core.gearbox import (conventional_gearbox, GearboxPlan, GearStep,
                                      plan_gearbox)
    from qrm_ros.core.geometry import (check_offset, crank_radius_for_stroke, Geometry,
                                       KinematicsError, MechanismState, SAFE_OFFSET_FRACTION,
                                       stroke_for_crank_radius)
    from qrm_ros.core.linkage import linkage_points, linkage_sizes, LinkagePoints, LinkageSizes
    from qrm_ros.core.mechanism_state import (input_angle_for_flywheel_angle,
                                              reversal_flywheel_angles, state)
    from qrm_ros.core.motor_stepper import MotorStepper, simulate, Simulation
    from qrm_ros.core.offset_inverses import (offset_for_cutting_speed, offset_for_speed_ratio,
                                              offset_for_time_ratio)
    from qrm_ros.core.peak_speeds import peak_ram_speeds, peak_speed_ratio
    from qrm_ros.core.sampling_bounds import (BOUNDED_FIGURES, figure_sampling_bounds,
                                              gap_after, GAP_PERIODS, GAP_SECONDS,
                                              steady_motion, SteadyMotion,
                                              SUPPORTED_RELATIVE_ERROR)
    from qrm_ros.core.speed_drive import pair_efforts, PairEfforts, peak_input_torque
    from qrm_ros.core.steady_figures import steady_theory, SteadyTheory
    from qrm_ros.core.steady_running import (energy_method_inertia,
                                             input_inertia_for_speed_fluctuation,
                                             speed_fluctuation, SpeedFluctuation)
    from qrm_ros.core.stepper import Stepper
    from qrm_ros.core.stepping import ShaperStepper
    from qrm_ros.core.stroke_adjustment import check_stroke, StrokeRamp
    from qrm_ros.core.stroke_efforts import efforts_with_stroke_screw
    from qrm_ros.core.stroke_monitor import PairReport, StrokeMonitor
    from qrm_ros.core.stroke_timing import (speed_ratio, speed_ratio_eq25, stroke_times,
                                            time_ratio, time_ratio_rk4)
    from qrm_ros.core.strokes import (find_reversals, find_stroke_pairs, measure_pair_efforts,
                                      PairEffortsMeasured, StrokePairs)


EXPORTED_FROM = declared_exports(__file__)  # name -> the module that defines it
__all__ = sorted(EXPORTED_FROM, key=str.lower)
__getattr__, __dir__ = lazy_attributes(globals(), EXPORTED_FROM)
