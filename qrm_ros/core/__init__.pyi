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
The one list of what qrm_ros.core exports, and from where.

lazy_loader reads it at run time (each name loads with its module on first use); type
checkers read it as the package's interface (``name as name``: a stub's import re-exports
only in that form).
"""

from .kinematics.cutting_speeds import (mean_cutting_speed as mean_cutting_speed,
                                        offset_for_mean_cutting_speed as offset_for_mean_cutting_speed)
from .kinematics.geometry import (check_offset as check_offset,
                                  crank_radius_for_stroke as crank_radius_for_stroke,
                                  Geometry as Geometry, KinematicsError as KinematicsError,
                                  MechanismState as MechanismState,
                                  SAFE_OFFSET_FRACTION as SAFE_OFFSET_FRACTION,
                                  stroke_for_crank_radius as stroke_for_crank_radius)
from .kinematics.linkage import (linkage_points as linkage_points, linkage_sizes as linkage_sizes,
                                 LinkagePoints as LinkagePoints, LinkageSizes as LinkageSizes)
from .kinematics.mechanism_state import (
                                         input_angle_for_flywheel_angle as input_angle_for_flywheel_angle,
                                         reversal_flywheel_angles as reversal_flywheel_angles,
                                         state as state)
from .kinematics.offset_inverses import (offset_for_cutting_speed as offset_for_cutting_speed,
                                         offset_for_speed_ratio as offset_for_speed_ratio,
                                         offset_for_time_ratio as offset_for_time_ratio)
from .kinematics.peak_speeds import (peak_ram_speeds as peak_ram_speeds,
                                     peak_speed_ratio as peak_speed_ratio)
from .kinematics.steady_figures import (steady_theory as steady_theory,
                                        SteadyTheory as SteadyTheory)
from .kinematics.stroke_timing import (speed_ratio as speed_ratio,
                                       speed_ratio_eq25 as speed_ratio_eq25,
                                       stroke_times as stroke_times, time_ratio as time_ratio,
                                       time_ratio_rk4 as time_ratio_rk4)
from .dynamics.chain import (DynamicsError as DynamicsError, Efforts as Efforts,
                             efforts as efforts, generalized_inertia as generalized_inertia,
                             Loads as Loads, MassProperties as MassProperties,
                             MotorDrive as MotorDrive, ram_load_force as ram_load_force)
from .dynamics.speed_drive import (pair_efforts as pair_efforts, PairEfforts as PairEfforts,
                                   peak_input_torque as peak_input_torque)
from .dynamics.stroke_efforts import (efforts_with_stroke_screw as efforts_with_stroke_screw)
from .stepping.stepper import (Stepper as Stepper)
from .stepping.stepping import (ShaperStepper as ShaperStepper)
from .stepping.stroke_adjustment import (check_stroke as check_stroke, StrokeRamp as StrokeRamp)
from .motor.motor_stepper import (MotorStepper as MotorStepper, simulate as simulate,
                                  Simulation as Simulation)
from .motor.steady_running import (energy_method_inertia as energy_method_inertia,
                                   input_inertia_for_speed_fluctuation as input_inertia_for_speed_fluctuation,
                                   speed_fluctuation as speed_fluctuation,
                                   SpeedFluctuation as SpeedFluctuation)
from .measurement.sampling_bounds import (BOUNDED_FIGURES as BOUNDED_FIGURES,
                                          figure_sampling_bounds as figure_sampling_bounds,
                                          gap_after as gap_after, GAP_PERIODS as GAP_PERIODS,
                                          GAP_SECONDS as GAP_SECONDS,
                                          steady_motion as steady_motion,
                                          SteadyMotion as SteadyMotion,
                                          SUPPORTED_RELATIVE_ERROR as SUPPORTED_RELATIVE_ERROR)
from .measurement.stroke_monitor import (PairReport as PairReport, StrokeMonitor as StrokeMonitor)
from .measurement.strokes import (find_reversals as find_reversals,
                                  find_stroke_pairs as find_stroke_pairs,
                                  measure_pair_efforts as measure_pair_efforts,
                                  PairEffortsMeasured as PairEffortsMeasured,
                                  StrokePairs as StrokePairs)
from .design.cutting_speed_hold import (cutting_speed as cutting_speed, hold_offset as hold_offset,
                                        HoldAnswer as HoldAnswer,
                                        reachable_cutting_speeds as reachable_cutting_speeds)
from .design.flywheel_design import (FlywheelSizing as FlywheelSizing,
                                     size_flywheel as size_flywheel)
from .design.gearbox import (conventional_gearbox as conventional_gearbox,
                             GearboxPlan as GearboxPlan, GearStep as GearStep,
                             plan_gearbox as plan_gearbox)
