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
Regenerate the golden logs in this folder (real shaper_sim and mcap_recorder processes).

    python3 dev.py run python test/data/make_golden_logs.py [NAME ...]

Each run starts the node at its first setting, paused until the recorder listens on every
topic, records, changes the settings through the node's parameter service (as `ros2 param
set` does), and moves on after enough steady stroke pairs at each setting (from the node's
diagnostics). Parameter changes only: their /parameter_events carry the node-clock stamp
the replay test needs.

The motor-drive runs (MOTOR_RUNS) start the node with its drive and loads, and reset it too
while it is paused: the first recorded sample is then where the node's motor stepper starts
its integration (input angle 0, the commanded speed), which a replay can start from bit for
bit. Each step sets some parameters and waits for stroke pairs of steady offset begun after
it (the motor's speed fluctuates with the load, so no pair is steady in speed).
"""

import math
import os
import sys
import tempfile
import time

from qrm_ros.cli.qrm_main import RECORDER_SETTLE_TIME, start_child, stop_child
from qrm_ros.node.main_job.main_job_conductor import Conductor, MainJobError
from qrm_ros.core.common.names import RECORDER_NODE_NAME

HERE = os.path.dirname(os.path.abspath(__file__))
TWO_PI = 2 * math.pi
# name -> list of settings (offset m, input speed rad/s, steady stroke pairs to record)
RUNS = {
    'steady_positive_offset': [(0.010, TWO_PI, 3)],
    'steady_negative_offset': [(-0.010, TWO_PI, 3)],
    'offset_and_speed_change': [(0.0, TWO_PI, 2), (0.012, TWO_PI, 2), (0.012, 9.0, 3),
                                (-0.008, TWO_PI, 2)],
}
# name -> (start-up parameters, steps: (parameters to set, stroke pairs to record after))
MOTOR_RUNS = {
    'motor_cutting_load': (
        {'drive': 'motor', 'coupling_offset': 0.010, 'input_speed': TWO_PI,
         'offset_rate_limit': 0.02, 'cutting_force': 400.0, 'ram_friction': 20.0,
         'cutting_length': 0.15},
        [({}, 2), ({'input_speed': 9.0}, 2), ({'coupling_offset': -0.008}, 2),
         ({'cutting_force': 800.0}, 2)]),
}


def _call(conductor, service_type, name, request):
    """Call a shaper_sim service (std_srvs) and wait for its success."""
    client = conductor.node.create_client(service_type, f'/shaper_sim/{name}')
    try:
        conductor.wait_for(client.service_is_ready, 30.0, f'/shaper_sim/{name}')
        future = client.call_async(request)
        conductor.wait_for(future.done, 10.0, f'the answer of /shaper_sim/{name}')
        if not future.result().success:
            raise MainJobError(f'/shaper_sim/{name} failed: {future.result().message}')
    finally:
        conductor.node.destroy_client(client)


def _recorder_listens(conductor):
    """Whether the recorder subscribes to every topic the replay compares."""
    return all(any(info.node_name == RECORDER_NODE_NAME
                   for info in conductor.node.get_subscriptions_info_by_topic(topic))
               for topic in ('/joint_states', '/ram/twist', '/parameter_events'))


def pairs_since(conductor, offset, since):
    """Count stroke pairs at a steady offset that began after `since` (s, node clock)."""
    return sum(1 for pair in conductor.pairs
               if pair.get('offset_steady') == 'true'
               and float(pair.get('coupling_offset', 'nan')) == offset
               and float(pair.get('pair_start', '-inf')) >= since)


def _run(name, start_up, steps, reset):
    """
    Record one run: start-up parameters, then (set parameters, wait for a condition) steps.

    The node is paused (and reset, for a replay from its integration's start) until the
    recorder listens on every topic, so the file misses nothing from its first sample on.
    """
    from std_srvs.srv import SetBool, Trigger
    path = os.path.join(HERE, name + '.mcap')
    if os.path.exists(path):
        os.remove(path)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', '142'))
    os.environ.update(env)
    logs = tempfile.mkdtemp(prefix='golden_')
    arguments = [item for key, value in start_up.items()
                 for item in ('-p', f'{key}:={value if isinstance(value, str) else repr(value)}')]
    sim = start_child('shaper_sim', arguments, os.path.join(logs, 'shaper_sim.log'), env)
    recorder = None
    conductor = Conductor()
    try:
        conductor.wait_for(conductor.sim_ready, 30.0, 'shaper_sim')
        _call(conductor, SetBool, 'pause', SetBool.Request(data=True))
        if reset:
            _call(conductor, Trigger, 'reset', Trigger.Request())
        recorder = start_child('mcap_recorder', ['-p', f'output:={path}'],
                               os.path.join(logs, 'mcap_recorder.log'), env)
        conductor.wait_for(lambda: _recorder_listens(conductor), 30.0, 'mcap_recorder')
        settled = time.monotonic() + RECORDER_SETTLE_TIME
        conductor.wait_for(lambda: time.monotonic() > settled, 10.0, 'the recorder to settle')
        _call(conductor, SetBool, 'pause', SetBool.Request(data=False))
        for parameters, done, what in steps:
            since = time.time()
            if parameters:
                conductor.set_parameters(**parameters)
            conductor.wait_for(lambda: done(conductor, since), 60.0, what)
    finally:
        conductor.close()
        if recorder is not None:
            stop_child(recorder)
        stop_child(sim)
    print(f'{path}: {os.path.getsize(path)} bytes (logs in {logs})')


def record(name, settings):
    """Record a speed-drive run: each setting held for its steady stroke pairs."""
    offset, speed, _ = settings[0]
    start_up = {'coupling_offset': offset, 'input_speed': speed, 'offset_rate_limit': 0.02}
    steps = [({'coupling_offset': offset, 'input_speed': speed},
              lambda conductor, since, o=offset, v=speed, n=pairs:
                  conductor.steady_pairs_at(o, since, v) >= n,
              f'{pairs} steady pairs at {offset} m, {speed} rad/s')
             for offset, speed, pairs in settings]
    _run(name, start_up, steps, reset=False)


def record_motor(name, run):
    """Record a motor-drive run from a reset: pairs at a steady offset after each step."""
    start_up, changes = run
    steps, offset = [], start_up['coupling_offset']
    for parameters, pairs in changes:
        offset = parameters.get('coupling_offset', offset)
        steps.append((parameters,
                      lambda conductor, since, o=offset, n=pairs:
                          pairs_since(conductor, o, since) >= n,
                      f'{pairs} pairs at {offset} m after setting {parameters}'))
    _run(name, start_up, steps, reset=True)


def main(names):
    for name in names or list(RUNS) + list(MOTOR_RUNS):
        try:
            if name in MOTOR_RUNS:
                record_motor(name, MOTOR_RUNS[name])
            else:
                record(name, RUNS[name])
        except MainJobError as error:
            sys.exit(f'make_golden_logs: {name}: {error}')


if __name__ == '__main__':
    main(sys.argv[1:])
