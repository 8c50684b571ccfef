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
"""What a package's ``__init__.pyi`` says it exports, read as the tests check it."""

import ast
import importlib
import os
from typing import Dict


def stub_exports(package: str) -> Dict[str, str]:
    """Map each name the package's stub imports to the module it names (absolute)."""
    folder = os.path.dirname(importlib.import_module(package).__file__)
    with open(os.path.join(folder, '__init__.pyi'), encoding='utf-8') as handle:
        tree = ast.parse(handle.read())
    return {alias.asname or alias.name: f'{package}.{statement.module}'
            for statement in tree.body if isinstance(statement, ast.ImportFrom)
            for alias in statement.names}
