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
The one exit-code policy of every command (a shell script or a launch system reads them).

0 done; 1 a failure while running (a write error, a child that exits, a time-out); 2 bad
options or unusable input (one line on stderr says what and the allowed range, nothing is
started or written); 3 done, but the input was damaged or incomplete (stderr says what was
lost); 128 + the signal's number when stopped by a signal (130 for Ctrl-C, 143 for SIGTERM).
"""

import signal

__all__ = ['EXIT_BAD_INPUT', 'EXIT_FAILURE', 'EXIT_INCOMPLETE', 'EXIT_INTERRUPTED', 'EXIT_OK',
           'EXIT_TERMINATED', 'exit_code_for_signal']

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_INCOMPLETE = 3


def exit_code_for_signal(signal_number: int) -> int:
    """Return the shell's exit status of a process stopped by that signal."""
    return 128 + signal_number


EXIT_INTERRUPTED = exit_code_for_signal(signal.SIGINT)  # 130, Ctrl-C
EXIT_TERMINATED = exit_code_for_signal(signal.SIGTERM)  # 143
