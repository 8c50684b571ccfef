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
A package's front door whose names load on first use (PEP 562), listed once.

A package (``qrm_ros.core``, ``qrm_ros.analysis``) names what it exports by importing it
under ``if TYPE_CHECKING:`` in its ``__init__``: type checkers and readers see real imports,
and these functions read the same lines from the source, so importing one light module of
the package does not load every heavy one with it. Plain Python: no numpy, no scipy.
"""

import ast
import importlib
from typing import Any, Callable, Dict, List, MutableMapping, Tuple

__all__ = ['declared_exports', 'lazy_attributes']


def declared_exports(init_file: str) -> Dict[str, str]:
    """Map each name the file imports under ``if TYPE_CHECKING:`` to its module."""
    with open(init_file, encoding='utf-8') as handle:
        tree = ast.parse(handle.read(), init_file)
    block = next(node for node in tree.body if isinstance(node, ast.If)
                 and isinstance(node.test, ast.Name) and node.test.id == 'TYPE_CHECKING')
    return {alias.name: statement.module for statement in block.body
            if isinstance(statement, ast.ImportFrom) and statement.module
            for alias in statement.names}


def lazy_attributes(namespace: MutableMapping[str, Any], exported: Dict[str, str]
                    ) -> Tuple[Callable[[str], Any], Callable[[], List[str]]]:
    """Return the package's ``__getattr__`` and ``__dir__`` for these exports."""
    def __getattr__(name: str) -> Any:
        module = exported.get(name)
        if module is None:
            raise AttributeError(f'module {namespace["__name__"]!r} has no attribute {name!r}')
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value  # the next lookup is a plain attribute
        return value

    def __dir__() -> List[str]:
        return sorted(set(namespace) | set(exported))
    return __getattr__, __dir__
