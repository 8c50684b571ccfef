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
The ROS parameters of the graph's nodes as the Foxglove protocol's parameters (qrm_bridge).

Each parameter is named ``<node>.<parameter>`` (``/shaper_sim.coupling_offset``), as
``foxglove_bridge`` names them, and read and set through the node's own parameter services, so
the node's checks apply: a refused value is not set, the client gets the value the node still
holds, and the node's reason goes to ``report`` (the bridge shows it to the clients).

The server calls get and set on its own threads while the ROS executor spins elsewhere: the
service clients are made on the executor's thread (``track``) and only called from here, each
answer awaited with a time-out.
"""

import threading
from typing import Callable, Dict, Iterable, List, Optional, Sequence, Tuple

from foxglove import Parameter as FoxgloveParameter, ParameterType as FoxgloveType
from rcl_interfaces.msg import Parameter as ParameterMessage, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python

from qrm_ros.node.bridge.bridge_services import call_from_thread

__all__ = ['PARAMETER_CALL_TIMEOUT', 'ParameterBridge', 'ParameterRefusal', 'from_ros',
           'split_name', 'to_ros']

PARAMETER_CALL_TIMEOUT = 2.0  # s, for each answer of a node's parameter service
NODE_SEPARATOR = '.'  # between the node's name and the parameter's (node names have no dot)


class ParameterRefusal(ValueError):
    """A value that cannot become a ROS parameter value, or a call without an answer."""


def split_name(name: str) -> Tuple[str, str]:
    """('/shaper_sim', 'coupling_offset') from '/shaper_sim.coupling_offset'."""
    node, separator, parameter = name.partition(NODE_SEPARATOR)
    if not separator or not node.startswith('/') or not parameter:
        raise ParameterRefusal(f'parameter name {name!r} is not /node.parameter')
    return node, parameter


def from_ros(name: str, value: ParameterValue) -> FoxgloveParameter:
    """Return a ROS ParameterValue as a Foxglove parameter (a whole double stays a double)."""
    if value.type == ParameterType.PARAMETER_NOT_SET:
        return FoxgloveParameter(name)
    native = parameter_value_to_python(value)
    if value.type == ParameterType.PARAMETER_DOUBLE:
        return FoxgloveParameter(name, value=float(native), type=FoxgloveType.Float64)
    if value.type == ParameterType.PARAMETER_DOUBLE_ARRAY:
        return FoxgloveParameter(name, value=[float(v) for v in native],
                                 type=FoxgloveType.Float64Array)
    if value.type == ParameterType.PARAMETER_BYTE_ARRAY:
        return FoxgloveParameter(name, value=b''.join(native), type=FoxgloveType.ByteArray)
    return FoxgloveParameter(name, value=list(native) if value.type in _ARRAYS else native)


_ARRAYS = (ParameterType.PARAMETER_BOOL_ARRAY, ParameterType.PARAMETER_INTEGER_ARRAY,
           ParameterType.PARAMETER_STRING_ARRAY)


def _is_integer(item) -> bool:
    return isinstance(item, int) and not isinstance(item, bool)


def to_ros(value, known_type: Optional[int] = None) -> ParameterValue:
    """
    Return a Foxglove parameter's native value as a ROS ParameterValue.

    A whole number sent for a double parameter (the app sends 0, not 0.0) is taken as that
    double when the parameter is known to be one (``known_type``).
    """
    message = ParameterValue()
    doubles = known_type in (ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_DOUBLE_ARRAY)
    if isinstance(value, bool):
        message.type, message.bool_value = ParameterType.PARAMETER_BOOL, value
    elif _is_integer(value) and not doubles:
        message.type, message.integer_value = ParameterType.PARAMETER_INTEGER, value
    elif _is_integer(value) or isinstance(value, float):
        message.type, message.double_value = ParameterType.PARAMETER_DOUBLE, float(value)
    elif isinstance(value, str):
        message.type, message.string_value = ParameterType.PARAMETER_STRING, value
    elif isinstance(value, bytes):
        message.type = ParameterType.PARAMETER_BYTE_ARRAY
        message.byte_array_value = [bytes([b]) for b in value]
    elif isinstance(value, list) and value and all(isinstance(v, bool) for v in value):
        message.type, message.bool_array_value = ParameterType.PARAMETER_BOOL_ARRAY, value
    elif isinstance(value, list) and value and all(_is_integer(v) for v in value) and not doubles:
        message.type, message.integer_array_value = ParameterType.PARAMETER_INTEGER_ARRAY, value
    elif isinstance(value, list) and value and all(
            _is_integer(v) or isinstance(v, float) for v in value):
        message.type = ParameterType.PARAMETER_DOUBLE_ARRAY
        message.double_array_value = [float(v) for v in value]
    elif isinstance(value, list) and value and all(isinstance(v, str) for v in value):
        message.type, message.string_array_value = ParameterType.PARAMETER_STRING_ARRAY, value
    else:
        raise ParameterRefusal(f'value {value!r} has no ROS parameter type (allowed: bool, '
                               'integer, double, string, bytes, or a non-empty list of one of '
                               'bool, integer, double, string)')
    return message


class _NodeClients:
    """The list, get and set services of one node."""

    def __init__(self, node: Node, target: str):
        self.clients = [node.create_client(kind, f'{target}/{service}') for kind, service in
                        ((ListParameters, 'list_parameters'), (GetParameters, 'get_parameters'),
                         (SetParameters, 'set_parameters'))]
        self.list, self.get, self.set = self.clients


def _answer(client, request):
    """Ask a node's parameter service; a missing or silent service is a refusal."""
    return call_from_thread(client, request, PARAMETER_CALL_TIMEOUT, ParameterRefusal)


class ParameterBridge:
    """Get and set the parameters of the graph's nodes by name, from the server's threads."""

    def __init__(self, node: Node, report: Callable[[str], None]):
        self._node = node
        self._report = report
        self._lock = threading.Lock()
        self._targets: Dict[str, _NodeClients] = {}
        self._types: Dict[str, int] = {}  # last seen ROS type of each parameter, by full name

    def track(self, node_names: Iterable[str]) -> None:
        """Keep service clients for exactly these nodes (call on the executor's thread)."""
        wanted = set(node_names)
        with self._lock:
            for gone in set(self._targets) - wanted:
                for client in self._targets.pop(gone).clients:
                    self._node.destroy_client(client)
            for new in wanted - set(self._targets):
                self._targets[new] = _NodeClients(self._node, new)

    def _clients(self, node_name: str) -> _NodeClients:
        with self._lock:
            clients = self._targets.get(node_name)
        if clients is None:
            raise ParameterRefusal(f'no node {node_name} in the graph')
        return clients

    def _values(self, node_name: str, names: Sequence[str],
                report: Optional[Callable[[str], None]] = None) -> List[FoxgloveParameter]:
        report = self._report if report is None else report
        clients = self._clients(node_name)
        values = list(_answer(clients.get, GetParameters.Request(names=list(names))).values)
        if len(values) != len(names):
            # rclpy answers nothing at all when one name is unknown: ask name by name, and
            # say which the node does not have.
            known, values = [], []
            for name in names:
                alone = list(_answer(clients.get, GetParameters.Request(names=[name])).values)
                if alone:
                    known.append(name)
                    values += alone
                else:
                    report(f'no parameter {name} on node {node_name}')
            names = known
        result = []
        for name, value in zip(names, values):
            full = node_name + NODE_SEPARATOR + name
            self._types[full] = value.type
            result.append(from_ros(full, value))
        return result

    def get(self, names: Sequence[str], quiet: bool = False) -> List[FoxgloveParameter]:
        """Return the named parameters (all of every node's when none are named)."""
        report = (lambda text: None) if quiet else self._report
        by_node: Dict[str, List[str]] = {}
        if names:
            for name in names:
                try:
                    node_name, parameter = split_name(name)
                except ParameterRefusal as refusal:
                    report(str(refusal))
                    continue
                by_node.setdefault(node_name, []).append(parameter)
        else:
            with self._lock:
                targets = dict(self._targets)
            for node_name, clients in sorted(targets.items()):
                try:
                    listed = _answer(clients.list, ListParameters.Request())
                except ParameterRefusal:
                    continue  # a node without parameter services, or one that just left
                by_node[node_name] = list(listed.result.names)
        result = []
        for node_name, parameters in by_node.items():
            try:
                result += self._values(node_name, parameters, report)
            except ParameterRefusal as refusal:
                if names:
                    report(str(refusal))
        return result

    def set(self, parameters: Sequence[FoxgloveParameter]) -> List[FoxgloveParameter]:
        """Set through each node's service; return the values the nodes hold afterwards."""
        by_node: Dict[str, List[ParameterMessage]] = {}
        for parameter in parameters:
            try:
                node_name, name = split_name(parameter.name)
                value = to_ros(parameter.get_value(), self._types.get(parameter.name))
            except ParameterRefusal as refusal:
                self._report(f'{parameter.name}: {refusal}')
                continue
            by_node.setdefault(node_name, []).append(ParameterMessage(name=name, value=value))
        result = []
        for node_name, messages in by_node.items():
            try:
                answer = _answer(self._clients(node_name).set,
                                 SetParameters.Request(parameters=messages))
                for message, outcome in zip(messages, answer.results):
                    if not outcome.successful:
                        self._report(f'{node_name}{NODE_SEPARATOR}{message.name}: '
                                     f'{outcome.reason}')
                result += self._values(node_name, [m.name for m in messages])
            except ParameterRefusal as refusal:
                self._report(str(refusal))
        return result
