"""Shared test helpers: an isolated ROS 2 context per test, and a node-plus-client harness."""

import os
import time

import pytest
from rcl_interfaces.msg import Log
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

# Keep DDS traffic on this machine and apart from other test runs and other ROS users: each
# pytest process gets its own domain, derived from its process id.
FIRST_TEST_DOMAIN_ID = 120
TEST_DOMAIN_COUNT = 90
WAIT_S = 30.0
SPIN_S = 0.05


def run_domain_id() -> int:
    """Return the ROS domain of this test run, unique among concurrent runs on the machine."""
    return FIRST_TEST_DOMAIN_ID + os.getpid() % TEST_DOMAIN_COUNT


def child_environment(domain_id: int | None = None) -> dict:
    """
    Return the environment for a child process that keeps its DDS traffic on this run's domain.

    :param domain_id: the domain; this run's own when None.
    :return: a copy of this process's environment with the ROS isolation variables set.
    """
    domain_id = run_domain_id() if domain_id is None else domain_id
    return dict(os.environ, ROS_DOMAIN_ID=str(domain_id),
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
        self.client = Node(client_name, context=context)
        self.errors = []
        self.client.create_subscription(Log, '/rosout', self._log_callback, 100)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self.executor.add_node(self.client)

    def _log_callback(self, msg: Log) -> None:
        if msg.name == self.node.get_name() and msg.level >= Log.ERROR:
            self.errors.append(msg.msg)

    def spin_until(self, condition, timeout_s: float = WAIT_S) -> None:
        """Spin until ``condition()`` holds; fail the test if it does not in time."""
        assert spin_until(self.executor, condition, timeout_s), 'timed out'

    def close(self) -> None:
        """Stop the executor and destroy both nodes."""
        self.executor.shutdown()
        self.node.destroy_node()
        self.client.destroy_node()
