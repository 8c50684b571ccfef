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
``qrm_urdf``: write the URDF of the shaper for a geometry (qrm_ros.recording.urdf_model).

``--foxglove-layout FILE`` also writes the Foxglove layout whose 3D panel frames that machine
(qrm_ros.recording.foxglove_layout).

Exit status: 0 written; 1 the file could not be written; 2 bad geometry (one line says why).
"""

import argparse
import sys
from typing import Optional, Sequence

from qrm_ros.cli.arguments import add_geometry_arguments, geometry_from_arguments
from qrm_ros.cli.exit_codes import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK
from qrm_ros.core.kinematics.geometry import KinematicsError
from qrm_ros.recording.atomic_files import staged_outputs
from qrm_ros.recording.foxglove_layout import foxglove_layout_text
from qrm_ros.recording.urdf_model import urdf_text, write_urdf


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run qrm_urdf; return the exit status."""
    parser = argparse.ArgumentParser(
        prog='qrm_urdf',
        description='Write the URDF of the shaper for a geometry (default: the node\'s '
                    'default geometry, the paper\'s Table 1).')
    parser.add_argument('-o', '--output', metavar='FILE',
                        help='write to FILE (default: standard output)')
    parser.add_argument('--foxglove-layout', metavar='FILE',
                        help='also write the Foxglove layout framing this machine to FILE '
                             '(config/foxglove_layout.json is the default geometry\'s)')
    add_geometry_arguments(parser)
    args = parser.parse_args(argv)
    try:
        geometry = geometry_from_arguments(args)
        if args.output:
            write_urdf(args.output, geometry)
        else:
            sys.stdout.write(urdf_text(geometry))
        if args.foxglove_layout:
            with staged_outputs() as stage:
                with open(stage(args.foxglove_layout), 'w') as layout:
                    layout.write(foxglove_layout_text(geometry))
    except KinematicsError as error:
        print(f'qrm_urdf: error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as error:
        # The target, not the temporary file it is written through.
        target = args.output if args.output else args.foxglove_layout
        print(f'qrm_urdf: error: cannot write {target}: {error.strerror or error}',
              file=sys.stderr)
        return EXIT_FAILURE
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
