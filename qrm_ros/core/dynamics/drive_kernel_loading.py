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
Loading the drives' compiled kernel (qrm_ros.core.dynamics.drive_kernel) on a thread of its own.

The lean acceleration and efforts and the speed drive's sample compiled (numba): importing
numba and loading the machine code take 0.3-1 s, so the first MotorStepper of a process (or
an offline run, qrm_simulate) starts loading them on a thread of its own; each segment, and
the efforts at each stamp, take whichever form is there (the two give the same numbers bit
for bit). That thread interleaves with the ticks (the node's
0.1 ms GIL switch interval) but for its C calls that keep the GIL: 3-7 ms each, a few, once
per process.
"""

import gc
import threading
from types import ModuleType
from typing import Optional

__all__ = ['COMPILED_DRIVE_KERNEL', 'CompiledKernel']


class CompiledKernel:
    """The compiled module once loaded (``module``), None while loading or without numba."""

    def __init__(self) -> None:
        self.module: Optional[ModuleType] = None
        self.loaded = threading.Event()  # set once loading ended, loaded or not
        self._lock = threading.Lock()
        self._loader: Optional[threading.Thread] = None

    def load(self) -> None:
        """Import the compiled kernel here and now (the loading thread's work)."""
        # The garbage collector stays off meanwhile: a full collection among numba's new
        # objects took 60 ms with the GIL held (a stall of every other thread); they stay for
        # the process's life, so they are frozen out of later collections (as the nodes
        # freeze theirs before they spin).
        collecting = gc.isenabled()
        gc.disable()
        try:
            # Imported here, not at the top: numba is optional and slow to load.
            from qrm_ros.core.dynamics import drive_kernel
        except ImportError:  # without numba: the Python form throughout
            pass
        else:
            self.module = drive_kernel
        finally:
            gc.freeze()
            if collecting:
                gc.enable()
            self.loaded.set()

    def start_loading(self) -> None:
        """Start loading on a daemon thread, once per process."""
        with self._lock:
            if self._loader is None:
                self._loader = threading.Thread(target=self.load, daemon=True,
                                                name='qrm_drive_kernel_loader')
                self._loader.start()


# The one per process: every MotorStepper, and the speed drive's sample, take their compiled
# forms from here.
COMPILED_DRIVE_KERNEL = CompiledKernel()
