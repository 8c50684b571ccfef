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
Benchmark: what writing the machine costs the recorder per joint state, in this run.

The baseline is what the recorder always does with a joint state: McapRunFile.add_message of
its recorded bytes. Measured on top: MachineChannels.joint_state, which decodes it, computes
the links' transforms and writes them on /tf (the recorder does both per joint state). The
joint states are real ones, from a golden log, to a file in a temporary folder. Prints the
median and spread (min-max of the repeat medians) in microseconds and the ratio of recording
with the machine to recording without it.

    python3 dev.py run python bench/bench_machine_transforms.py [--repeats 7]
"""

import argparse
import os
import statistics
import tempfile
import time

from qrm_ros.core.kinematics.geometry import Geometry
from qrm_ros.core.common.names import GEOMETRY_METADATA, JOINT_STATES_TOPIC
from qrm_ros.recording.bag_reader import open_run
from qrm_ros.recording.machine_channels import MachineChannels
from qrm_ros.recording.mcap_run_file import COMPRESSIONS, McapRunFile

GOLDEN = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'test', 'data',
                      'steady_positive_offset.mcap')


def per_message_microseconds(messages, geometry, folder, with_machine, name):
    """Record the joint states (and their transforms); return microseconds per joint state."""
    run_file = McapRunFile(os.path.join(folder, name), COMPRESSIONS['zstd'], 1_000_000_000)
    channel = run_file.add_channel('/joint_states', 'sensor_msgs/msg/JointState', '[]', '')
    machine = MachineChannels(run_file)
    if with_machine:
        machine.start(geometry, messages[0].log_time)
    start = time.perf_counter()
    for message in messages:
        run_file.add_message(channel, message.log_time, message.publish_time, message.data)
        if with_machine:
            machine.joint_state(message.log_time, message.publish_time, message.data)
    elapsed = time.perf_counter() - start
    run_file.finish()
    assert machine.dropped == 0
    return elapsed / len(messages) * 1e6


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--repeats', type=int, default=7)
    args = parser.parse_args()
    run = open_run(GOLDEN)
    geometry = Geometry(**{k: float(v) for k, v in run.metadata[GEOMETRY_METADATA].items()})
    messages = list(run.messages([JOINT_STATES_TOPIC]))
    plain, machine = [], []
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(args.repeats):  # interleaved, so machine load hits both alike
            plain.append(per_message_microseconds(messages, geometry, folder, False,
                                                  f'plain{repeat}.mcap'))
            machine.append(per_message_microseconds(messages, geometry, folder, True,
                                                    f'machine{repeat}.mcap'))
    ratios = [m / p for m, p in zip(machine, plain)]
    print(f'{len(messages)} joint states, {args.repeats} repeats')
    for label, values in (('joint state alone', plain), ('with its transforms', machine)):
        print(f'{label:>22}: {statistics.median(values):7.1f} us per joint state '
              f'({min(values):.1f}-{max(values):.1f})')
    print(f'{"ratio":>22}: {statistics.median(ratios):.2f}x ({min(ratios):.2f}-{max(ratios):.2f});'
          f' the transforms add {statistics.median(machine) - statistics.median(plain):.1f} us, '
          f'{(statistics.median(machine) - statistics.median(plain)) * 1e-3:.1%} of a core at '
          '1 kHz')


if __name__ == '__main__':
    main()
