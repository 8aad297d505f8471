"""Fixtures shared by the tests: an isolated ROS 2 context per test."""

import os

import pytest
import rclpy
from rclpy.context import Context

# Keep DDS traffic on this machine and apart from other test runs and other ROS users: each
# pytest process gets its own domain, derived from its process id.
FIRST_TEST_DOMAIN_ID = 120
TEST_DOMAIN_COUNT = 90


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
