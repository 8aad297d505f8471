"""
The package as a ROS 2 Jazzy user builds and runs it: colcon, the install tree, ``--ros-args``.

Under plain pytest this builds the checkout with ``colcon build`` in a temporary workspace, checks
the install tree the way ``ros2 run`` uses it, starts the installed executables with the
workspace's environment, and runs ``colcon test`` and ``colcon test-result`` in that workspace.
Under ``colcon test`` (which sets ``COLCON`` and puts this package's install prefix on
``AMENT_PREFIX_PATH``) the same checks run against that install tree, and no workspace is built.
"""

import os
from pathlib import Path
import shlex
import shutil
import subprocess
import sys
from typing import NamedTuple
from xml.etree import ElementTree

from conftest import (child_environment, kill_leftovers, PACKAGE_DIR, run_domain_id, spin_until,
                      stop_process)
from diagnostic_msgs.msg import DiagnosticArray
from followbot.transport import FASTDDS_PROFILE_VARIABLE
from followbot_sim.score import score_values
from geometry_msgs.msg import Twist
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

PACKAGE = 'followbot'
# What ros2 run finds in lib/followbot: the console scripts of setup.py.
EXECUTABLES = ('follower', 'sim', 'followbot', 'scorecard', 'benchmark', 'calibrate', 'replay')
# Installed data: share/followbot/<folder> holds the checkout's files matching these patterns.
INSTALLED_DATA = {'models': ('*.xml',), 'config': ('*.yaml', '*.xml')}
UNDER_COLCON_TEST = 'COLCON' in os.environ
BUILD_TIMEOUT_S = 600.0
# colcon test runs the whole suite a second time, from the install tree's environment.
COLCON_TEST_TIMEOUT_S = 3600.0
RUN_TIMEOUT_S = 120.0
NAMESPACE = '/robot1'
EXPECTED_NODES = {('follower', NAMESPACE), ('followbot_sim', NAMESPACE)}
# The book's follower published here; the turtlebot's cmd_vel_mux takes teleop commands there.
TELEOP_TOPIC = 'cmd_vel_mux/input/teleop'
# A -p after --params-file overrides the file: a speed below the file's 0.7 m/s shows it did.
OVERRIDDEN_SPEED_MPS = 0.5
DRIVEN_DISTANCE_M = 3.0
MAX_DISTANCE_FROM_LINE_M = 0.05
# Under colcon test, from the install tree: every case of the lint modules, and this module's
# install-tree checks, must pass (not be skipped).
LINT_MODULES = ('test_flake8', 'test_pep257', 'test_xmllint', 'test_package_xml')
INSTALL_TREE_TESTS = (
    'test_colcon_build_installs_what_ros2_run_looks_up',
    'test_installed_nodes_follow_the_line_under_a_namespace_with_remaps',
    'test_installed_followbot_runs_both_nodes_under_a_namespace')


class Workspace(NamedTuple):
    """A colcon install of this package and the environment its setup script gives."""

    prefix: Path
    environment: dict
    root: Path | None

    @property
    def share(self) -> Path:
        """Return the package's share directory, where the data files are installed."""
        return self.prefix / 'share' / PACKAGE

    def executable(self, name: str) -> str:
        """Return the path of an executable where ``ros2 run followbot <name>`` finds it."""
        return str(self.prefix / 'lib' / PACKAGE / name)


def colcon_executable() -> str:
    """Return the colcon beside this Python (a virtualenv's) or else the one on PATH."""
    search_path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get('PATH', '')])
    colcon = shutil.which('colcon', path=search_path)
    assert colcon, 'colcon is not installed: pip install -r requirements-test.txt'
    return colcon


def run_colcon(root: Path, verb: str, *arguments: str, timeout_s: float):
    """Run a colcon verb on this checkout in the workspace ``root``; return the result."""
    return subprocess.run(
        [colcon_executable(), '--log-base', str(root / 'log'), verb, *arguments],
        cwd=root, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, timeout=timeout_s)


def workspace_paths(root: Path) -> list:
    """Return the arguments that place this checkout's build and install in ``root``."""
    return ['--paths', str(PACKAGE_DIR), '--build-base', str(root / 'build'),
            '--install-base', str(root / 'install')]


def sourced_environment(setup_script: Path) -> dict:
    """Return the environment after sourcing a colcon setup script in bash, as a user does."""
    # colcon's setup.bash reads unset variables: it fails under `set -u`.
    output = subprocess.run(
        ['bash', '-c', f'set +u; source {shlex.quote(str(setup_script))} && env -0'],
        stdout=subprocess.PIPE, check=True).stdout.decode()
    return dict(entry.split('=', 1) for entry in output.split('\0') if '=' in entry)


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """Yield the install to check: colcon test's own, or a fresh build of this checkout."""
    if UNDER_COLCON_TEST:
        from ament_index_python.packages import get_package_prefix
        yield Workspace(Path(get_package_prefix(PACKAGE)), dict(os.environ), None)
        return
    root = tmp_path_factory.mktemp('colcon_ws')
    build = run_colcon(root, 'build', *workspace_paths(root), timeout_s=BUILD_TIMEOUT_S)
    assert build.returncode == 0, build.stdout
    yield Workspace(root / 'install' / PACKAGE,
                    sourced_environment(root / 'install' / 'setup.bash'), root)


def workspace_environment(workspace: Workspace, fastdds_profile: Path | None = None) -> dict:
    """Return the workspace's environment on this run's isolated domain, with this profile."""
    environment = child_environment(base=workspace.environment)
    environment.pop(FASTDDS_PROFILE_VARIABLE, None)
    if fastdds_profile is not None:
        environment[FASTDDS_PROFILE_VARIABLE] = str(fastdds_profile)
    return environment


def run_python(workspace: Workspace, code: str, cwd: Path) -> list:
    """Run Python code in the workspace's environment; return its output lines."""
    result = subprocess.run(
        [sys.executable, '-c', code], env=workspace_environment(workspace), cwd=cwd,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stdout
    return result.stdout.splitlines()


def test_colcon_build_installs_what_ros2_run_looks_up(workspace, tmp_path):
    prefix, share = workspace.prefix, workspace.share
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).is_file()
    assert (share / 'package.xml').read_bytes() == (PACKAGE_DIR / 'package.xml').read_bytes()
    for folder, patterns in INSTALLED_DATA.items():
        source = {path.name: path.read_bytes()
                  for pattern in patterns for path in (PACKAGE_DIR / folder).glob(pattern)}
        installed = {path.name: path.read_bytes() for path in (share / folder).iterdir()}
        assert source and installed == source, folder
    for name in EXECUTABLES:
        path = Path(workspace.executable(name))
        assert path.is_file() and os.access(path, os.X_OK), path

    # From outside the checkout, the workspace's environment finds the package through the
    # ament index, as ros2 run and ros2 pkg prefix do, and imports the installed modules.
    located = run_python(workspace, '\n'.join([
        'from ament_index_python.packages import get_package_prefix, '
        'get_package_share_directory',
        'import followbot, followbot_sim',
        'from followbot.package_files import share_file',
        f'print(get_package_prefix({PACKAGE!r}))',
        f'print(get_package_share_directory({PACKAGE!r}))',
        "print(share_file('models', 'scene.xml'))",
        'print(followbot.__file__)',
        'print(followbot_sim.__file__)',
    ]), cwd=tmp_path)
    found_prefix, found_share, scene, *module_files = located
    assert (found_prefix, found_share) == (str(prefix), str(share))
    installed_modules = all(path.startswith(f'{prefix}{os.sep}') for path in module_files)
    # A build of our own is a plain install: the modules are copies in the install tree.
    assert installed_modules or workspace.root is None, located
    # Installed modules read the installed data; those of a --symlink-install are the
    # checkout's own and read the checkout's.
    assert scene == str((share if installed_modules else PACKAGE_DIR) / 'models' / 'scene.xml')


def test_installed_nodes_follow_the_line_under_a_namespace_with_remaps(
        workspace, ros_context, tmp_path):
    config = workspace.share / 'config'
    ros_arguments = ['--ros-args', '-r', f'__ns:={NAMESPACE}', '-r', f'cmd_vel:={TELEOP_TOPIC}',
                     '--params-file', str(config / 'followbot.yaml')]
    # As the README has ros2 run users do: with Fast DDS's default segment, frames go by UDP
    # and some are lost, and in lockstep each lost frame holds the simulator for its timeout.
    environment = workspace_environment(workspace, config / 'fastdds_shm.xml')
    simulator = subprocess.Popen(
        [workspace.executable('sim'), *ros_arguments,
         '-p', 'real_time_factor:=0.0', '-p', 'lockstep:=true'],
        env=environment, cwd=tmp_path)
    follower = subprocess.Popen(
        [workspace.executable('follower'), *ros_arguments,
         '-p', 'use_sim_time:=true', '-p', f'linear_speed_mps:={OVERRIDDEN_SPEED_MPS}'],
        env=environment, cwd=tmp_path)
    client = Node('install_tree_client', context=ros_context)
    commands, scores = [], []
    client.create_subscription(Twist, f'{NAMESPACE}/{TELEOP_TOPIC}', commands.append, 100)
    client.create_subscription(DiagnosticArray, '/diagnostics',
                               lambda msg: scores.append(score_values(msg)), 10)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        assert spin_until(executor, lambda: any(
            score and float(score['progress_m']) >= DRIVEN_DISTANCE_M for score in scores)), (
            f'{len(commands)} commands, last score {scores[-1:]}')
        # The graph may lag the data: wait until it shows both nodes.
        assert spin_until(executor, lambda: EXPECTED_NODES <= set(
            client.get_node_names_and_namespaces())), client.get_node_names_and_namespaces()
        remapped_away = {topic: (client.count_publishers(topic), client.count_subscribers(topic))
                         for topic in ('/cmd_vel', f'{NAMESPACE}/cmd_vel')}
        assert stop_process(follower) == 0
        assert stop_process(simulator) == 0
    finally:
        kill_leftovers(follower, simulator)
        executor.shutdown()
        client.destroy_node()

    assert remapped_away == {'/cmd_vel': (0, 0), f'{NAMESPACE}/cmd_vel': (0, 0)}
    speeds_mps = [command.linear.x for command in commands]
    assert max(speeds_mps) == pytest.approx(OVERRIDDEN_SPEED_MPS)
    score = [score for score in scores if score][-1]
    assert float(score['max_distance_from_line_m']) < MAX_DISTANCE_FROM_LINE_M


def test_installed_followbot_runs_both_nodes_under_a_namespace(workspace, tmp_path):
    share = workspace.share
    domain_id = run_domain_id()
    launcher = subprocess.run(
        [workspace.executable('followbot'), '--domain-id', str(domain_id),
         '--duration', '5', '--real-time-factor', '0', '--lockstep',
         '--ros-args', '-r', f'__ns:={NAMESPACE}', '--params-file',
         str(share / 'config' / 'followbot.yaml')],
        env=workspace_environment(workspace), cwd=tmp_path, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, timeout=RUN_TIMEOUT_S)
    output = launcher.stdout
    assert launcher.returncode == 0, output
    # The installed profile, found through the ament index.
    assert f'Fast DDS profile {share}/config/fastdds_shm.xml.' in output.splitlines()[0]
    logger_namespace = NAMESPACE.strip('/')
    assert f'[{logger_namespace}.follower]: Line found.' in output, output
    assert f'[{logger_namespace}.followbot_sim]: Run of 5.0 s simulated time done' in output


def junit_outcomes(report: Path) -> dict:
    """Return (module, test name without parameters) -> outcomes, from a JUnit XML report."""
    outcomes = {}
    for case in ElementTree.parse(report).getroot().iter('testcase'):
        results = [child.tag for child in case if child.tag in ('failure', 'error', 'skipped')]
        key = (case.get('classname').rsplit('.', 1)[-1], case.get('name').split('[')[0])
        outcomes.setdefault(key, set()).add(results[0] if results else 'passed')
    return outcomes


def test_colcon_test_passes_in_the_workspace(workspace):
    if UNDER_COLCON_TEST:
        pytest.skip('this is a colcon test run already')
    root = workspace.root
    # The soak runs minutes: the outer run has it already. (--pytest-args takes the rest.)
    tested = run_colcon(root, 'test', *workspace_paths(root), '--test-result-base',
                        str(root / 'test_results'), '--pytest-args', '-m', 'not soak',
                        timeout_s=COLCON_TEST_TIMEOUT_S)
    result = run_colcon(root, 'test-result', '--test-result-base', str(root / 'test_results'),
                        '--verbose', timeout_s=RUN_TIMEOUT_S)
    assert tested.returncode == 0 and result.returncode == 0, (
        tested.stdout[-5000:] + result.stdout)
    outcomes = junit_outcomes(root / 'test_results' / PACKAGE / 'pytest.xml')
    assert all(outcome <= {'passed', 'skipped'} for outcome in outcomes.values())
    this_module = Path(__file__).stem
    required = [key for key in outcomes if key[0] in LINT_MODULES]
    required += [(this_module, name) for name in INSTALL_TREE_TESTS]
    assert {key[0] for key in required} >= set(LINT_MODULES)
    not_passed = {key: outcomes.get(key) for key in required if outcomes.get(key) != {'passed'}}
    assert not not_passed
    assert outcomes[(this_module, 'test_colcon_test_passes_in_the_workspace')] == {'skipped'}
    assert ('test_soak', 'test_five_minute_soak_of_both_nodes_keeps_memory_flat') not in outcomes
    assert ('test_soak', 'test_growth_of_exactly_the_limit_passes') in outcomes
