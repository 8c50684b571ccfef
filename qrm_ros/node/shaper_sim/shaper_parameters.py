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
The shaper_sim node's parameters as data: default, unit, meaning, rule and effect of each.

Adding a parameter is one PARAMETERS entry (plus its use). A rule says in words what it
allows and why a value breaks it; refusal_reason() builds every refusal the same way, so
`ros2 param set` always prints '<name> = <value> refused: <why>; allowed ...'. ROS-free:
parameter_services turns specs into descriptors and reasons into SetParametersResults.
"""

import math
from typing import Any, Callable, NamedTuple, Optional, Tuple

from qrm_ros.core.design.cutting_speed_hold import CUTTING_SPEED_DEFINITIONS, unreachable_reason
from qrm_ros.core.dynamics.chain import Loads, MassProperties, MotorDrive, parameter_names
from qrm_ros.core.kinematics.geometry import Geometry, KinematicsError
from qrm_ros.core.common.names import DRIVES, MOTOR_PREFIX
from qrm_ros.core.dynamics.physical_ranges import (MAX_INPUT_SPEED, MAX_MAGNITUDES,
                                                   MIN_INPUT_SPEED, motor_speed_band_problem,
                                                   motor_time_constant_problem)
from qrm_ros.node.shaper_sim.stroke_rules import (commanded_geometry, commanded_stroke,
                                                  one_hold_at_a_time, slot_holds_crank,
                                                  stroke_holds_workpiece, StrokeLengthRange,
                                                  time_ratio_reachable)

__all__ = ['AtLeast', 'DoubleRange', 'DRIVES', 'GEOMETRY_NAMES', 'MARKER_SLICING_RATE',
           'MOTOR_PREFIX', 'NonEmptyText', 'OffOrRange', 'OneOf', 'ParameterSpec', 'PARAMETERS',
           'PositiveLength', 'SymmetricRange', 'View', 'allowed_text', 'change_refusal',
           'default_values', 'refusal_reason', 'shown', 'start_up_refusal']

GEOMETRY_NAMES = Geometry.field_names()
# Hz: above this publish rate the node sends a marker frame one marker per tick, after a tick
# that only builds it. Building and converting a whole frame takes 0.3-0.4 ms in a running
# node (rclpy's conversion holds the GIL): a 1 ms period absorbs that, a 0.25 ms one (4 kHz)
# does not, and the next tick came a period late at every frame.
MARKER_SLICING_RATE = 1000.0
_PAPER = Geometry.paper()
# Hz: the slowest marker rate but off (a frame every 100 s); a smaller rate has a period that
# no clock holds (5e-324 Hz overflows integer nanoseconds).
MIN_MARKER_RATE = 0.01
# m/s: the largest cutting speed a target may ask (shapers cut at 0.1-1 m/s).
MAX_CUTTING_SPEED_TARGET = 100.0


def shown(value):
    """Format a value as reasons print it: 0.0225, not 0.022500000000000003."""
    return f'{value:.6g}' if isinstance(value, float) else repr(value)


class View(NamedTuple):
    """What a rule may look at: every value after the change, the geometry, the command."""

    values: dict
    geometry: Geometry
    speed_command: float  # the input speed command in force after the change
    stroke_in_force: float = 0.0  # m (0: the start-up stroke, crank_radius's)
    stroke_moving: bool = False  # the stroke has not reached stroke_length yet


def _with_unit(unit):
    return f' {unit}' if unit else ''


def _double_problem(value, low, high, allowed):
    """Why a value is not a finite double within [low, high] (None: unbounded side)."""
    if not isinstance(value, float):
        return f'must be a floating-point number in {allowed}'
    if not math.isfinite(value):
        return f'not finite; allowed range {allowed}'
    if (low is not None and value < low) or (high is not None and value > high):
        return f'outside the allowed range {allowed}'
    return None


class DoubleRange(NamedTuple):
    """A fixed inclusive range, also published in the descriptor."""

    low: float
    high: float

    def descriptor_bounds(self, geometry, view=None):
        return self.low, self.high

    def allowed(self, unit, view):
        return f'[{shown(self.low)}, {shown(self.high)}]{_with_unit(unit)}'

    def problem(self, value, unit, view):
        return _double_problem(value, self.low, self.high, self.allowed(unit, view))


class SymmetricRange(NamedTuple):
    """|value| <= a limit that depends on the geometry or on another parameter."""

    limit: Callable[[View], float]
    why: Callable[[View], str]
    fixed_by_geometry: bool  # then the descriptor can publish the range

    def bounds(self, view):
        limit = self.limit(view)
        return -limit, limit

    def descriptor_bounds(self, geometry, view=None):
        if not self.fixed_by_geometry:
            return None
        return self.bounds(View({}, geometry, 0.0))

    def allowed(self, unit, view):
        low, high = self.bounds(view)
        return f'[{shown(low)}, {shown(high)}]{_with_unit(unit)} ({self.why(view)})'

    def problem(self, value, unit, view):
        return _double_problem(value, *self.bounds(view), self.allowed(unit, view))


class PositiveLength(NamedTuple):
    """A geometry length: finite, > 0, and whatever else Geometry itself demands."""

    extra: str = ''

    def descriptor_bounds(self, geometry, view=None):
        return None

    def allowed(self, unit, view):
        return f'a finite value > 0{_with_unit(unit)}{self.extra}'

    def problem(self, value, unit, view):
        allowed = self.allowed(unit, view)
        return _double_problem(value, None, None, allowed) or (
            None if value > 0.0 else f'must be {allowed}')


class AtLeast(NamedTuple):
    """
    A finite double >= minimum (> minimum if strict); minimum None: any finite double.

    magnitude, if given, also bounds |value| (a bound no shaper leaves: physical_ranges).
    """

    minimum: Optional[float]
    strict: bool = False
    magnitude: Optional[float] = None

    def descriptor_bounds(self, geometry, view=None):
        return None

    def allowed(self, unit, view):
        if self.minimum is None:
            if self.magnitude is None:
                return f'a finite value{_with_unit(unit)}'
            return (f'a finite value in [{shown(-float(self.magnitude))}, '
                    f'{shown(float(self.magnitude))}]{_with_unit(unit)}')
        relation = '>' if self.strict else '>='
        most = '' if self.magnitude is None else f' and <= {shown(float(self.magnitude))}'
        return (f'a finite value {relation} {shown(float(self.minimum))}{most}'
                f'{_with_unit(unit)}')

    def problem(self, value, unit, view):
        allowed = self.allowed(unit, view)
        problem = _double_problem(value, None, None, allowed)
        if problem:
            return problem
        outside = self.magnitude is not None and abs(value) > self.magnitude
        if self.minimum is not None:
            outside |= value <= self.minimum if self.strict else value < self.minimum
        return f'outside the allowed range {allowed}' if outside else None


class OffOrRange(NamedTuple):
    """0 (off), or a fixed inclusive range of positive values (rates: a period must exist)."""

    low: float
    high: float

    def descriptor_bounds(self, geometry, view=None):
        return 0.0, self.high

    def allowed(self, unit, view):
        return f'0 (off) or [{shown(self.low)}, {shown(self.high)}]{_with_unit(unit)}'

    def problem(self, value, unit, view):
        allowed = self.allowed(unit, view)
        if value == 0.0 and isinstance(value, float):
            return None
        return _double_problem(value, self.low, self.high, allowed)


class NonEmptyText(NamedTuple):
    """A non-blank string that a message can carry whole (frame ids): no NUL or control."""

    def descriptor_bounds(self, geometry, view=None):
        return None

    def allowed(self, unit, view):
        return 'a non-empty string without control characters'

    def problem(self, value, unit, view):
        if (isinstance(value, str) and value.strip()
                and not any(ord(character) < 32 or ord(character) == 127
                            for character in value)):
            return None
        return f'must be {self.allowed(unit, view)}'


class OneOf(NamedTuple):
    """One of a few words (modes)."""

    choices: Tuple[str, ...]

    def descriptor_bounds(self, geometry, view=None):
        return None

    def allowed(self, unit, view):
        return 'one of ' + ', '.join(repr(choice) for choice in self.choices)

    def problem(self, value, unit, view):
        if value in self.choices:
            return None
        return f'must be {self.allowed(unit, view)}'


class ParameterSpec(NamedTuple):
    """One parameter: default, unit, meaning, rule, extra checks and what setting it does."""

    default: object
    unit: str
    description: str
    read_only: bool
    rule: object
    # (value, view) -> why a value that passes the rule is still refused, or None.
    checks: Tuple[Callable[[float, View], Optional[str]], ...] = ()
    # (node, value) -> None: what a new value does beyond being stored.
    apply: Optional[Callable[[Any, Any], None]] = None


def _max_input_speed_checks():
    def below_input_speed(value, view):
        speed = abs(view.values['input_speed'])
        if value < speed:
            return (f'below |input_speed| = {shown(speed)} rad/s; lower input_speed first')
        return None

    def below_speed_command(value, view):
        if value < abs(view.speed_command):
            return (f'below the speed command in force ({shown(view.speed_command)} rad/s, '
                    'from input_speed_cmd); command a lower speed first')
        return None
    return below_input_speed, below_speed_command


_STRUCTURAL = 'Structural: set at start-up only.'


def _target_reachable(value, view):
    """Refuse a cutting speed the safe offsets cannot give at the speed command."""
    target = view.values['cutting_speed_target']
    if target == 0.0:
        return None
    return unreachable_reason(commanded_geometry(view), view.speed_command, target,
                              view.values['cutting_speed_definition'])


def _judges_changes_only(check):
    """Mark CHECK as one that judges a live change only, not a start-up value.

    Who commands the offset is a question for a change: at start-up coupling_offset is where
    the offset starts, and a hold set beside it commands the offset from there.
    """
    check.changes_only = True
    return check


def _offset_commanded_by(hold: str, unit: str):
    """Return the check that refuses a hand-set offset while HOLD (a target) is set."""
    @_judges_changes_only
    def commanded(value, view):
        target = view.values[hold]
        if target == 0.0:
            return None
        return (f'the offset is commanded by {hold} = {shown(target)}{unit}; set {hold} to 0 '
                'to command coupling_offset by hand (or set both in one atomic call)')
    return commanded


_offset_by_hand = _offset_commanded_by('cutting_speed_target', ' m/s')
_offset_by_time_ratio = _offset_commanded_by('time_ratio_target', '')


def _stepper_limit(name, default, unit, what, rule):
    """Return the spec of a live limit on how fast the stepper follows a command (set_limits)."""
    return ParameterSpec(default, unit, f'{what} toward its command.', False, rule,
                         apply=lambda node, value: node.stepper.set_limits(**{name: value}))


PARAMETERS = {
    'coupling_radius': ParameterSpec(
        _PAPER.coupling_radius, 'm', 'Coupling crank radius r1: radius of the input pin in '
        f'the yoke coupling. > 0. {_STRUCTURAL}', True, PositiveLength()),
    'crank_radius': ParameterSpec(
        _PAPER.crank_radius, 'm', 'Crank radius r on the flywheel at start-up (sets the ram '
        'stroke until stroke_length commands another). 0 < crank_radius < pivot_distance. '
        f'{_STRUCTURAL}', True,
        PositiveLength(' and < pivot_distance')),
    'pivot_distance': ParameterSpec(
        _PAPER.pivot_distance, 'm', 'Distance h from the flywheel centre down to the lever '
        f'pivot. > crank_radius. {_STRUCTURAL}', True, PositiveLength()),
    'ram_height': ParameterSpec(
        _PAPER.ram_height, 'm', 'Height H of the ram line above the lever pivot: ram '
        f'position = H tan(lever angle). > 0. {_STRUCTURAL}', True, PositiveLength()),
    'crank_phase': ParameterSpec(
        _PAPER.crank_phase, 'rad', 'Phase of the crank pin on the flywheel (0: a positive '
        f'offset raises the time ratio). {_STRUCTURAL}', True, DoubleRange(-math.pi, math.pi)),
    'coupling_offset': ParameterSpec(
        0.0, 'm', 'Commanded coupling offset (input shaft above the flywheel axis when > 0). '
        'The offset in force moves toward it at offset_rate_limit. |offset| <= '
        '0.9 * coupling_radius (the coupling locks at coupling_radius). While a hold '
        '(cutting_speed_target, time_ratio_target) commands the offset it is refused live; '
        'at start-up it is where the offset starts, and the hold moves it from there.', False,
        SymmetricRange(
            lambda view: float(view.geometry.max_safe_offset),
            lambda view: ('|offset| <= max_safe_offset = 0.9 x coupling_radius '
                          f'{shown(view.geometry.coupling_radius)} m'), True),
        (_offset_by_hand, _offset_by_time_ratio),
        apply=lambda node, value: node.command_offset()),
    'cutting_speed_target': ParameterSpec(
        0.0, 'm/s', 'Cutting speed to hold (0: off, the offset follows coupling_offset). While '
        'it is set the node commands the offset (at offset_rate_limit) that gives this '
        'cutting speed at the input speed command in force, recomputed when the command '
        'changes; a target out of reach within the offset safety limit is refused, and if a '
        'later speed change puts it out of reach the nearest reachable offset is held (WARN '
        'on /diagnostics).', False, AtLeast(0.0, False, MAX_CUTTING_SPEED_TARGET),
        (_target_reachable, one_hold_at_a_time),
        apply=lambda node, value: node.command_offset()),
    'cutting_speed_definition': ParameterSpec(
        CUTTING_SPEED_DEFINITIONS[0], '', "What cutting_speed_target means: 'mean', the cutting "
        "stroke's length over its time (the figure of shop tables), or 'peak', the largest "
        'cutting speed in the stroke.', False, OneOf(CUTTING_SPEED_DEFINITIONS),
        (_target_reachable,), apply=lambda node, value: node.command_offset()),
    'offset_rate_limit': _stepper_limit(
        'offset_rate_limit', 0.005, 'm/s',
        'Speed at which the offset actuator moves the offset', DoubleRange(1e-6, 1.0)),
    'max_input_speed': ParameterSpec(
        60.0, 'rad/s', 'Largest |input speed| accepted from input_speed and '
        'input_speed_cmd.', False, DoubleRange(MIN_INPUT_SPEED, MAX_INPUT_SPEED),
        _max_input_speed_checks()),
    'input_speed': ParameterSpec(
        2.0 * math.pi, 'rad/s', 'Commanded input shaft speed (at start, on reset and when '
        'set; input_speed_cmd also commands it). Negative runs the shaper in reverse. '
        '|input_speed| <= max_input_speed.', False,
        SymmetricRange(lambda view: view.values['max_input_speed'],
                       lambda view: '|input_speed| <= max_input_speed', False),
        apply=lambda node, value: node.command_speed(value)),
    'input_acceleration_limit': _stepper_limit(
        'input_acceleration_limit', 20.0, 'rad/s^2',
        'Acceleration at which the input shaft speed ramps', DoubleRange(1e-3, 1e5)),
    'publish_rate': ParameterSpec(
        100.0, 'Hz', 'Rate of the timer that steps and publishes the mechanism (node clock). '
        'Set at start-up only.', True, DoubleRange(1.0, 1e4)),
    'marker_rate': ParameterSpec(
        30.0, 'Hz', 'Rate of the linkage_markers MarkerArray (the mechanism drawn for RViz and '
        'Foxglove, at the latest published sample); 0 turns it off. Sent right after a tick, '
        f'so at most publish_rate; above a publish_rate of {MARKER_SLICING_RATE:.0f} Hz one '
        'marker a tick.', False, OffOrRange(MIN_MARKER_RATE, 1000.0),
        apply=lambda node, value: node.set_marker_rate(value)),
    'frame_id': ParameterSpec(
        'shaper_base', '', 'frame_id of the published joint_states and ram/twist headers. '
        'Non-empty.', False, NonEmptyText()),
}


_MASS_MEANINGS = {
    'input_inertia': 'Inertia J1 of the input assembly about O1 (input shaft, coupling crank, '
                     'motor rotor and gearbox referred to the input shaft)',
    'flywheel_inertia': 'Inertia J2 of the flywheel assembly about O2 (bull gear, crank, the '
                        "coupling's slotted member)",
    'lever_inertia': 'Inertia J3 of the slotted lever about its pivot O3',
    'lever_mass': 'Lever mass m3 (for its weight)',
    'lever_com_distance': "Distance l3 from O3 to the lever's centre of mass, toward the ram",
    'ram_mass': 'Mass m4 of the ram with its tool head',
    'gravity': 'Gravitational acceleration g, along -y',
}
_MOTOR_MEANINGS = {
    'speed_stiffness': 'Motor torque per rad/s of input speed below its reference, referred to '
                       'the input shaft (drive: motor): the slope of an induction motor\'s '
                       'torque-speed curve near its operating point',
    'max_torque': 'Largest motor torque at the input shaft (drive: motor), the pull-out '
                  'torque there; a load that needs more stalls the machine',
}
_LOAD_MEANINGS = {
    'cutting_force': 'Cutting force F_c on the ram while the tool cuts (ram moving toward -x, '
                     '|ram position| <= cutting_length / 2)',
    'ram_friction': 'Coulomb friction force on the ram, against its motion',
    'cutting_length': 'Length L_c of the workpiece, centred on ram position 0; at most the ram '
                      'stroke',
}


def _cutting_length_within_stroke(value, view):
    stroke = commanded_stroke(view)
    if value > stroke:
        return f'longer than the ram stroke, {shown(stroke)} m'
    return None


def _some_inertia(value, view):
    if view.values['input_inertia'] + view.values['flywheel_inertia'] <= 0.0:
        return ('input_inertia and flywheel_inertia may not both be 0 (the drive would see no '
                'inertia)')
    return None


def _motor_not_too_stiff(value, view):
    values = view.values
    return motor_time_constant_problem(values['input_inertia'], values['flywheel_inertia'],
                                       values[MOTOR_PREFIX + 'speed_stiffness'])


def _motor_band_wide_enough(value, view):
    values = view.values
    return motor_speed_band_problem(values[MOTOR_PREFIX + 'speed_stiffness'],
                                    values[MOTOR_PREFIX + 'max_torque'])


_EXTRA_CHECKS = {'cutting_length': (_cutting_length_within_stroke,),
                 'input_inertia': (_some_inertia, _motor_not_too_stiff),
                 'flywheel_inertia': (_some_inertia, _motor_not_too_stiff),
                 'speed_stiffness': (_motor_not_too_stiff, _motor_band_wide_enough),
                 'max_torque': (_motor_band_wide_enough,)}


def _dynamics_parameters():
    """Declare the mass properties and the loads (all live) from the dynamics' own fields."""
    specs = {}
    for kind, defaults, meanings in (
            (MassProperties, MassProperties.small_shaper(), _MASS_MEANINGS),
            (Loads, Loads.none(), _LOAD_MEANINGS),
            (MotorDrive, MotorDrive.small_shaper(), _MOTOR_MEANINGS)):
        units, limits = kind.units(), kind.lower_limits()
        for name, parameter in zip(kind.field_names(), parameter_names(kind)):
            specs[parameter] = ParameterSpec(
                float(getattr(defaults, name)), units[name],
                f'{meanings[name]}. Live: the efforts follow at once.', False,
                AtLeast(*limits[name], MAX_MAGNITUDES.get(name)), _EXTRA_CHECKS.get(name, ()),
                lambda node, value: node.update_dynamics())
    return specs


PARAMETERS.update(_dynamics_parameters())
PARAMETERS['drive'] = ParameterSpec(
    DRIVES[0], '', "How the input shaft is driven: 'speed', an ideal speed source that follows "
    "the commanded speed at input_acceleration_limit whatever the load (the efforts are what "
    "it must supply); 'motor', a motor whose torque follows its speed error "
    "(motor_speed_stiffness, up to motor_max_torque), so the input speed follows the "
    'equation of motion and fluctuates with the load. Live: the switch keeps the state.',
    False, OneOf(DRIVES),
    apply=lambda node, value: node.set_drive(value))
PARAMETERS.update({
    'max_crank_radius': ParameterSpec(
        0.07, 'm', "Largest crank radius the bull gear's slot allows (the stroke screw's "
        'travel): bounds stroke_length. crank_radius <= max_crank_radius < pivot_distance. '
        f'{_STRUCTURAL}', True, PositiveLength(' and crank_radius <= it < pivot_distance'),
        (slot_holds_crank,)),
    'stroke_length': ParameterSpec(
        0.0, 'm', 'Commanded ram stroke (the stroke-adjust screw). The crank radius in force '
        'moves toward the one that gives it, r = S h / sqrt(4 H^2 + S^2), at '
        'stroke_rate_limit; 0 means the stroke of crank_radius (which only sets the radius '
        'at start-up: from there this is the one command). Not below cutting_length; live '
        'under either drive. The time-ratio and cutting-speed holds follow it.',
        False,
        StrokeLengthRange(), (stroke_holds_workpiece,),
        apply=lambda node, value: node.command_stroke()),
    'stroke_rate_limit': ParameterSpec(
        0.01, 'm/s', 'Speed at which the stroke screw moves the ram stroke toward '
        'stroke_length.', False, DoubleRange(1e-6, 1.0),
        apply=lambda node, value: node.stepper.stroke.set_rate_limit(value)),
    'time_ratio_target': ParameterSpec(
        0.0, '', 'Time ratio to hold (0: off), forward running. While it is set the node '
        'commands the offset (at offset_rate_limit) that gives this ratio at the stroke '
        'commanded, recomputed when the stroke changes; a ratio out of reach within the '
        'offset safety limit is refused, and if a later stroke change puts it out of reach '
        'the nearest reachable offset is held (WARN on /diagnostics). Not together with '
        'cutting_speed_target.', False, AtLeast(0.0),
        (time_ratio_reachable, one_hold_at_a_time),
        apply=lambda node, value: node.command_offset()),
})


def default_values():
    return {name: spec.default for name, spec in PARAMETERS.items()}


def allowed_text(name, view):
    """Say what a parameter accepts, in words (descriptors and refusals say the same)."""
    spec = PARAMETERS[name]
    return spec.rule.allowed(spec.unit, view)


def refusal_reason(name, value, view, starting=False):
    """
    Why a parameter may not take a value, or None if it may.

    view holds every value as it would be after the change. Read-only parameters are refused
    while running; at start-up (starting=True) they are checked like the others. Reasons
    name the parameter, the value and what is allowed: they are what `ros2 param set` prints.
    """
    spec = PARAMETERS[name]
    refused = f'{name} = {value!r} refused: '
    if spec.read_only and not starting:
        return refused + _read_only_reason(name, value, view)
    problem = spec.rule.problem(value, spec.unit, view)
    if problem:
        return refused + problem
    for check in spec.checks:
        if starting and getattr(check, 'changes_only', False):
            continue
        problem = check(value, view)
        if problem:
            return f'{refused}{problem} (allowed range {allowed_text(name, view)})'
    return None


def change_refusal(changed, values, geometry, speed_command, stroke_in_force=0.0,
                   stroke_moving=False):
    """
    Return the first refusal of a change, judged as a whole (all values after it), or None.

    changed: the new values by name (names of no parameter are not judged); values: those in
    force; speed_command: the input speed command in force, which a change that sets
    input_speed sets too.
    """
    changed = {name: value for name, value in changed.items() if name in PARAMETERS}
    candidate = dict(values)
    # Read-only values never change, so the candidate keeps them (reasons show them).
    candidate.update((name, value) for name, value in changed.items()
                     if not PARAMETERS[name].read_only)
    if 'input_speed' in changed:
        speed_command = candidate['input_speed']
    view = View(candidate, geometry, speed_command, stroke_in_force, stroke_moving)
    for name, value in changed.items():
        reason = refusal_reason(name, value, view)
        if reason:
            return reason
    return None


def start_up_refusal(values, geometry):
    """Return the first refusal of the start-up values, or None (input_speed judged first)."""
    view = View(values, geometry, values['input_speed'])
    # input_speed before max_input_speed, so a too-fast start names input_speed.
    for name in sorted(PARAMETERS, key=lambda name: name != 'input_speed'):
        reason = refusal_reason(name, values[name], view, starting=True)
        if reason:
            return reason
    return None


def _read_only_reason(name, value, view):
    spec = PARAMETERS[name]
    reason = (f'{name} is read-only (structural; set it at start-up, e.g. in '
              f'config/shaper.yaml with --params-file); it stays {view.values[name]!r}'
              f'{_with_unit(spec.unit)}')
    if name in GEOMETRY_NAMES and isinstance(value, float):
        changed = dict(view.geometry.as_dict(), **{name: value})
        try:
            Geometry(**changed)
        except KinematicsError as error:
            reason += f'; the value would also break the geometry: {error}'
    return reason
