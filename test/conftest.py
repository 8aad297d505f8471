"""Shared test helpers: an isolated ROS 2 context per test, and a node-plus-client harness."""

import functools
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

# Sets MUJOCO_GL (EGL, headless) before mujoco is first imported.
import followbot_sim  # noqa: F401, I100
from followbot_sim.domains import reserve_domains
from geometry_msgs.msg import Twist
from hypothesis import HealthCheck, settings
import mujoco
import pytest
from rcl_interfaces.msg import Log
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_srvs.srv import SetBool, Trigger

# The package's source directory, found from this file, not the working directory: pytest runs
# from the checkout, colcon test from the package source directory.
PACKAGE_DIR = Path(__file__).resolve().parent.parent
# Keep DDS traffic on this machine and apart from other test runs and other ROS users: each
# pytest process reserves its own block of domains (a scorecard's two workers use the run's
# domain and the next) with lock files, held until the process ends, which the tools' default
# domains respect too. A domain derived from the process id alone was shared by two runs now
# and then: one run's follower then showed up in the other's graph.
FIRST_TEST_DOMAIN_ID = 120
TEST_DOMAIN_COUNT = 90
DOMAINS_PER_RUN = 2
WAIT_S = 30.0
# How long a node process may take to stop after SIGINT.
STOP_TIMEOUT_S = 15.0
SPIN_S = 0.05
ROSOUT_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Property-based tests: a short fixed budget in every run, derandomised so that CI sees the
# same examples each time; FOLLOWBOT_FUZZ_EXAMPLES=5000 (say) for a longer, random search.
FUZZ_EXAMPLES_VARIABLE = 'FOLLOWBOT_FUZZ_EXAMPLES'
DEFAULT_FUZZ_EXAMPLES = 40
_LONG_FUZZ = FUZZ_EXAMPLES_VARIABLE in os.environ
settings.register_profile(
    'followbot', max_examples=int(os.environ.get(FUZZ_EXAMPLES_VARIABLE,
                                                 DEFAULT_FUZZ_EXAMPLES)),
    derandomize=not _LONG_FUZZ, deadline=None, database=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                           HealthCheck.data_too_large, HealthCheck.large_base_example])
settings.load_profile('followbot')


@functools.cache
def _run_domains():
    """Reserve this test run's block of domains, once; the cache holds it until the run ends."""
    return reserve_domains(DOMAINS_PER_RUN, FIRST_TEST_DOMAIN_ID, TEST_DOMAIN_COUNT)


def run_domain_id() -> int:
    """Return the ROS domain of this test run, unique among concurrent runs on the machine."""
    return _run_domains().first


def child_environment(domain_id: int | None = None, base: dict | None = None) -> dict:
    """
    Return the environment for a child process that keeps its DDS traffic on this run's domain.

    :param domain_id: the domain; this run's own when None.
    :param base: the environment to start from, such as a sourced workspace's; this process's
        own when None.
    :return: a copy of ``base`` with the ROS isolation variables set.
    """
    domain_id = run_domain_id() if domain_id is None else domain_id
    return dict(os.environ if base is None else base, ROS_DOMAIN_ID=str(domain_id),
                ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')


@pytest.fixture
def ros_context(monkeypatch):
    """Yield an initialised rclpy Context on this run's own, localhost-only domain."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.setenv('ROS_DOMAIN_ID', str(run_domain_id()))
    context = Context()
    rclpy.init(context=context, domain_id=run_domain_id())
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


def node_command(module: str, *ros_arguments: str) -> list:
    """Return the command line that starts a followbot module as its own process."""
    return [sys.executable, '-m', module, '--ros-args', *ros_arguments]


def refusal(parse, argv, capsys) -> str:
    """
    Return the one error line with which a command refuses its arguments.

    :param parse: the command's function that reads its command line (argparse inside).
    :param argv: the arguments, without the program name.
    :param capsys: pytest's capsys fixture.
    :return: the line ``PROG: error: ...``; the command must have ended with exit code 2 and
        written no other error line.
    """
    with pytest.raises(SystemExit) as exit_info:
        parse(argv)
    assert exit_info.value.code == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if ': error: ' in line]
    assert len(errors) == 1, errors
    return errors[0]


def stop_process(process: subprocess.Popen) -> int:
    """Stop a child as Ctrl-C would and return its exit code; kill it if it does not stop."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        return process.wait(STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        raise


def kill_leftovers(*processes: subprocess.Popen) -> None:
    """Kill the child processes that a failed test left running."""
    for process in processes:
        if process.poll() is None:
            process.kill()


def spin_until(executor, condition, timeout_s: float = WAIT_S) -> bool:
    """
    Spin an executor until ``condition()`` holds or the time runs out.

    :param executor: the executor to spin.
    :param condition: a callable returning a truth value.
    :param timeout_s: wall-clock seconds to wait at most.
    :return: whether the condition held.
    """
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=SPIN_S)
    return bool(condition())


class NodeHarness:
    """A node under test and a client node in one executor; the node's errors are recorded."""

    def __init__(self, context, node, client_name: str):
        """
        Put the node and a new client node in an executor, and listen to /rosout.

        :param context: the rclpy Context of both nodes.
        :param node: the node under test.
        :param client_name: the client node's name.
        """
        self.node = node
        # Kept, not asked of the node per message: a test may destroy the node while /rosout
        # still delivers its last lines.
        self._node_name = node.get_name()
        self.client = Node(client_name, context=context)
        self.logs = []
        # /rosout keeps a history for late joiners (transient local), so the node's start-up
        # messages, logged before this client existed, arrive too.
        self.client.create_subscription(Log, '/rosout', self._log_callback, ROSOUT_QOS)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self.executor.add_node(self.client)

    def _log_callback(self, msg: Log) -> None:
        if msg.name == self._node_name:
            self.logs.append(msg)

    @property
    def errors(self) -> list:
        """Return the texts of the node's error and fatal log messages so far."""
        return [msg.msg for msg in self.logs if msg.level >= Log.ERROR]

    @property
    def warnings(self) -> list:
        """Return the texts of the node's warnings so far."""
        return [msg.msg for msg in self.logs if msg.level == Log.WARN]

    def spin_until(self, condition, timeout_s: float = WAIT_S) -> None:
        """Spin until ``condition()`` holds; fail the test if it does not in time."""
        assert spin_until(self.executor, condition, timeout_s), 'timed out'

    def close(self) -> None:
        """Stop the executor and destroy both nodes."""
        self.executor.shutdown()
        self.node.destroy_node()
        self.client.destroy_node()


class SimHarness(NodeHarness):
    """A simulator running as fast as possible and a client that commands it."""

    def __init__(self, context, *overrides, command_type=Twist):
        """
        Start the simulator with ``real_time_factor`` 0 and any parameter overrides.

        :param context: the rclpy Context of both nodes.
        :param overrides: rclpy Parameters for the simulator.
        :param command_type: Twist or TwistStamped, the type the client sends on cmd_vel.
        """
        from followbot_sim.sim_node import SimulatorNode
        super().__init__(context, SimulatorNode(context=context, parameter_overrides=[
            Parameter('real_time_factor', value=0.0), *overrides]), 'sim_test_client')
        self.simulator = self.node
        self.command_type = command_type
        self.cmd_vel = self.client.create_publisher(command_type, 'cmd_vel', 10)
        self.spin_until(lambda: self.cmd_vel.get_subscription_count() > 0)

    @property
    def world(self):
        """Return the simulator's world, the ground truth."""
        return self.simulator.world

    def command(self, linear_mps, angular_radps=0.0):
        """Publish a Twist, wait until the simulator has it and return the time it came."""
        received = self.simulator.commands_received
        command = self.command_type()
        twist = command if self.command_type is Twist else command.twist
        twist.linear.x = float(linear_mps)
        twist.angular.z = float(angular_radps)
        self.cmd_vel.publish(command)
        self.spin_until(lambda: self.simulator.commands_received > received)
        return self.world.time_s

    def run_until(self, time_s):
        """Spin until simulated time reaches ``time_s``."""
        self.spin_until(lambda: self.world.time_s >= time_s)

    def call(self, service_type, name, request):
        """Call one of the simulator's services and return the response."""
        client = self.client.create_client(service_type, f'/followbot_sim/{name}')
        try:
            self.spin_until(client.service_is_ready)
            future = client.call_async(request)
            self.spin_until(future.done)
            return future.result()
        finally:
            self.client.destroy_client(client)

    def pause(self, paused=True):
        """Pause or resume the simulation through its service."""
        return self.call(SetBool, 'pause', SetBool.Request(data=paused))

    def step(self):
        """Advance a paused simulation through its step service."""
        return self.call(Trigger, 'step', Trigger.Request())

    def reset(self):
        """Put the robot back at the start through the reset service."""
        return self.call(Trigger, 'reset', Trigger.Request())


@pytest.fixture
def sim(ros_context):
    """Yield a simulator running as fast as possible, with a client, on this run's domain."""
    harness = SimHarness(ros_context)
    yield harness
    harness.close()


@pytest.fixture(scope='session')
def opengl():
    """Skip the test unless a ``mujoco.Renderer`` can be made here."""
    try:
        renderer = mujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 8, 8)
    except Exception as error:
        pytest.skip(f'mujoco.Renderer cannot be created (no OpenGL context?): {error}')
    renderer.close()
