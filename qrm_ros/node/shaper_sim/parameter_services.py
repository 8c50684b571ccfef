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
The shaper_sim parameters through rclpy: descriptors, start-up values, the set services.

The rules themselves are data (qrm_ros.node.shaper_sim.shaper_parameters); this module is where
they meet rclpy, and the one place that uses rclpy internals. Three things rclpy does not offer
publicly: the start-up overrides (to name a refused value and to report unknown names), a
check before rclpy's descriptor checks (whose wording names no allowed range), and the
parameter services' request decoding (which raises out of the executor on a malformed
ParameterValue type and would stop the node). test_parameter_services.py exercises each, so
an rclpy update that breaks them fails a test.
"""

import difflib
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.node.shaper_sim.shaper_parameters import (allowed_text, change_refusal,
                                                       default_values, GEOMETRY_NAMES, PARAMETERS,
                                                       refusal_reason, start_up_refusal, View)
from rcl_interfaces.msg import (FloatingPointRange, Parameter as ParameterMessage,
                                ParameterDescriptor, SetParametersResult)
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

__all__ = ['ShaperParameterNode', 'WARNING_PERIOD', 'coerce_integers_to_doubles',
           'start_up_overrides']

WARNING_PERIOD = 1.0  # s, throttle for repeated warnings
# Overrides rclpy declares itself; not this node's to report as unknown.
_RCLPY_PARAMETERS = ('use_sim_time', 'start_type_description_service')
_PAPER = Geometry.paper()  # the defaults of the geometry parameters


def coerce_integers_to_doubles(parameters: List[Parameter]) -> List[Parameter]:
    """Take an integer for a double parameter as that double (`ros2 param set /shaper_sim X 0`)."""
    return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            if (p.type_ == Parameter.Type.INTEGER and p.name in PARAMETERS
                and isinstance(PARAMETERS[p.name].default, float)) else p
            for p in parameters]


def start_up_overrides(node: Node) -> Dict[str, Parameter]:
    """Parameter values given at start-up (--params-file, -p, parameter_overrides)."""
    return node._parameter_overrides  # rclpy internal (see the module docstring)


def _parameter_descriptor(name: str, view: View, geometry: Geometry) -> ParameterDescriptor:
    """Describe a parameter: meaning and unit, read-only flag, allowed values in words."""
    spec = PARAMETERS[name]
    unit = f' [{spec.unit}]' if spec.unit else ''
    descriptor = ParameterDescriptor(
        name=name, description=f'{spec.description}{unit}', read_only=spec.read_only,
        additional_constraints=f'allowed: {allowed_text(name, view)}')
    bounds = spec.rule.descriptor_bounds(geometry, view)
    if bounds is not None:
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=bounds[0], to_value=bounds[1], step=0.0)]
    return descriptor


def _declare_checked(node: Node, name: str, declared: Mapping[str, object],
                     geometry: Geometry) -> object:
    """
    Declare a parameter with its descriptor; return its start-up value.

    declared: the values declared so far. A value rclpy refuses raises ValueError with this
    node's reason (rclpy's own wording names no allowed range).
    """
    spec = PARAMETERS[name]
    view = View(dict(default_values(), **declared), geometry, 0.0)
    descriptor = _parameter_descriptor(name, view, geometry)
    try:
        return node.declare_parameter(name, spec.default, descriptor).value
    except (InvalidParameterTypeException, InvalidParameterValueException) as error:
        given = start_up_overrides(node).get(name)
        value = given.value if given is not None else None
        number = _number_in_text(value)
        if number is not None and isinstance(spec.default, float):
            # The YAML reader keeps a number it cannot hold as a double (1.0e-310 underflows)
            # as text: judge the number it says.
            reason: Optional[str] = refusal_reason(name, number, view, starting=True) or (
                f'{name} = {value} refused: ROS reads it as text, not as a double (too small '
                f'or too large for one); allowed: {allowed_text(name, view)}')
        elif isinstance(error, InvalidParameterTypeException) and isinstance(spec.default,
                                                                             float):
            reason = (
                f'{name} = {value!r} refused: must be a double, written with a decimal point '
                f'(e.g. {spec.default!r}); allowed: {allowed_text(name, view)}')
        else:
            reason = refusal_reason(name, value, view, starting=True)
        raise ValueError(reason or f'{name}: {error}; allowed: '
                         f'{allowed_text(name, view)}') from None


def _number_in_text(value: object) -> Optional[float]:
    """Return the number a text value writes (e.g. '1.0e-310'), or None."""
    if not isinstance(value, str):
        return None
    try:
        return float(value)
    except ValueError:
        return None


def _report_unknown_overrides(node: Node) -> None:
    """Warn of each start-up value that names no parameter (with the nearest name)."""
    unknown = sorted(set(start_up_overrides(node)) - set(PARAMETERS) - set(_RCLPY_PARAMETERS))
    for name in unknown:
        close = difflib.get_close_matches(name, PARAMETERS, n=1)
        hint = f' (did you mean {close[0]}?)' if close else ''
        node.get_logger().warning(
            f'start-up parameter {name} ignored: no such parameter of {node.get_name()}'
            f'{hint}; its parameters: {", ".join(sorted(PARAMETERS))}')


def _undeclared_refusal(node: Node, parameters: Sequence[Parameter]) -> str:
    """Why a change naming undeclared parameters is refused ('' when it names none)."""
    unknown = [p.name for p in parameters if not node.has_parameter(p.name)]
    # rclpy's own refusal of an undeclared name names none ("parameter(s): []").
    if not unknown:
        return ''
    return (f'{", ".join(unknown)}: no such parameter of {node.get_name()}; its parameters: '
            f'{", ".join(sorted(PARAMETERS))}')


class _GuardedParameterServices:
    """The set services' callbacks: a malformed request gets a reason instead of raising."""

    def __init__(self, node: Node):
        self._node = node

    def _decoded(self, messages: Sequence[ParameterMessage]
                 ) -> Tuple[Optional[List[Parameter]], Optional[SetParametersResult]]:
        """(parameters, None), or (None, a refusal) when a message cannot be decoded."""
        parameters = []
        for message in messages:
            try:
                parameters.append(Parameter.from_parameter_msg(message))
            except (ValueError, TypeError) as error:
                reason = (f'{message.name}: malformed request refused: {error} (ParameterValue'
                          f'.type must be one of {[t.value for t in Parameter.Type]})')
                self._node.get_logger().warning(reason, throttle_duration_sec=WARNING_PERIOD)
                return None, SetParametersResult(successful=False, reason=reason)
        return parameters, None

    def on_set_parameters(self, request, response):
        for message in request.parameters:
            parameters, refusal = self._decoded([message])
            response.results.append(refusal or self._node.set_parameters_atomically(parameters))
        return response

    def on_set_parameters_atomically(self, request, response):
        parameters, refusal = self._decoded(request.parameters)
        response.result = refusal or self._node.set_parameters_atomically(parameters)
        return response


def _guard_parameter_services(node: Node) -> None:
    """Answer malformed set requests to node's parameter services with a reason."""
    guard = _GuardedParameterServices(node)
    guarded = {SetParameters: guard.on_set_parameters,
               SetParametersAtomically: guard.on_set_parameters_atomically}
    for service in node.services:  # rclpy's parameter services: one of each type
        if service.srv_type in guarded:
            service.callback = guarded[service.srv_type]


class ShaperParameterNode(Node):
    """
    A node with the shaper_sim parameters: every change judged by their rules, then applied.

    The subclass calls declare_shaper_parameters() first in its set-up (which gives
    self._values, the values in force by name, and self._geometry) and
    judge_parameter_changes() once it can take a change; it says the input speed command in
    force (speed_command, which the rules look at) and has the methods the specs' effects
    call (ParameterSpec.apply).
    """

    _values: Dict[str, Any]
    _geometry: Geometry

    def declare_shaper_parameters(self) -> None:
        """Declare every parameter, the geometry first; ValueError: a start-up value refused."""
        values: Dict[str, Any] = {}
        self._values = values
        for name in GEOMETRY_NAMES:
            values[name] = _declare_checked(self, name, values, _PAPER)
        # Geometry errors name the field, the value and the limit (raised to the command).
        self._geometry = Geometry(**{name: values[name] for name in GEOMETRY_NAMES})
        for name in PARAMETERS:
            if name not in GEOMETRY_NAMES:
                values[name] = _declare_checked(self, name, values, self._geometry)
        reason = start_up_refusal(values, self._geometry)
        if reason:
            raise ValueError(f'start-up value refused: {reason}')
        _report_unknown_overrides(self)

    def judge_parameter_changes(self) -> None:
        """From now on, judge every change by the rules and apply it by the specs."""
        _guard_parameter_services(self)
        self.add_pre_set_parameters_callback(coerce_integers_to_doubles)
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

    @property
    def speed_command(self) -> float:
        """The input speed command in force (the subclass's to say)."""
        raise NotImplementedError

    @property
    def stroke_in_force(self) -> float:
        """The ram stroke in force, m (0.0: the start-up one; the subclass says)."""
        return 0.0

    @property
    def stroke_moving(self) -> bool:
        """Whether the stroke is still moving toward its command (the subclass says)."""
        return False

    def set_parameters_atomically(self, parameter_list):
        """Check our parameters first, so every refusal gets this node's full reason."""
        parameter_list = coerce_integers_to_doubles(parameter_list)
        reason = (_undeclared_refusal(self, parameter_list)
                  or self._refusal(parameter_list))
        if reason:
            self.get_logger().warning(reason)
            return SetParametersResult(successful=False, reason=reason)
        return super().set_parameters_atomically(parameter_list)

    def set_parameters(self, parameter_list):
        return [self.set_parameters_atomically([p]) for p in parameter_list]

    def _refusal(self, parameters):
        """Return the first refusal of a change, judged as a whole (all values after it)."""
        return change_refusal({p.name: p.value for p in parameters}, self._values,
                              self._geometry, self.speed_command, self.stroke_in_force,
                              self.stroke_moving)

    def _check_parameters(self, parameters):
        reason = self._refusal(parameters)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, parameters):
        for parameter in parameters:
            spec = PARAMETERS.get(parameter.name)
            if spec is None:
                continue
            value = self._values[parameter.name] = parameter.value
            if spec.apply is not None:
                spec.apply(self, value)
            self.get_logger().info(f'{parameter.name} set to {value!r}')
