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
Output files written all or nothing.

Each file is written under a temporary name beside its target and renamed over it only when
every output of the command was written: a failed or interrupted run leaves no half file and
no mix of new and old outputs (a rename within one folder is atomic on POSIX).

    with staged_outputs() as stage:
        write_json(document, stage('results.json'))
        figure.savefig(stage('figs/fig10.png'), format='png')
"""

import contextlib
import os
import tempfile
from typing import Callable, Iterator, List, Tuple


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def staged_outputs() -> Iterator[Callable[[str], str]]:
    """Yield stage(target) -> temporary path; on success rename them all, else remove them."""
    staged: List[Tuple[str, str]] = []

    def stage(target: str) -> str:
        folder, name = os.path.split(os.path.abspath(target))
        try:
            handle, temporary = tempfile.mkstemp(prefix=f'.{name}.', suffix='.part', dir=folder)
        except OSError as error:  # name the file the user asked for, not the temporary one
            raise OSError(error.errno, error.strerror, target) from None
        os.close(handle)
        os.chmod(temporary, 0o666 & ~_umask())  # what a plain open() would have made
        staged.append((temporary, target))
        return temporary

    try:
        yield stage
        for temporary, _ in staged:
            with open(temporary, 'rb+') as handle:
                os.fsync(handle.fileno())  # the data is on disk before the name points at it
        while staged:
            temporary, target = staged[0]
            os.replace(temporary, target)
            staged.pop(0)
    finally:
        for temporary, _ in staged:
            with contextlib.suppress(OSError):
                os.unlink(temporary)
