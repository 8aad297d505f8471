"""Service requests sent again until answered, against real services over DDS."""

from conftest import spin_until
from followbot_sim.answered_requests import AnsweredRequests, SimulatorPause
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import SetBool

SERVICE = '/followbot_sim/pause'
RETRY_S = 0.2


class PauseServer:
    """A real SetBool service that remembers what it was asked."""

    def __init__(self, context, name='pause_server'):
        """Create the node and its service."""
        self.received = []
        self.node = Node(name, context=context)
        self.node.create_service(SetBool, SERVICE, self.pause)

    def pause(self, request, response):
        """Answer every request with success."""
        self.received.append(request.data)
        response.success = True
        response.message = 'paused' if request.data else 'running'
        return response


@pytest.fixture
def client_node(ros_context):
    """Yield a node for the clients, and an executor spinning it."""
    node = Node('pause_client', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    yield node, executor
    executor.shutdown()
    node.destroy_node()


def test_a_request_is_sent_once_the_service_is_there_and_not_again_once_answered(
        ros_context, client_node):
    node, executor = client_node
    requests = AnsweredRequests(node.create_client(SetBool, SERVICE), RETRY_S)
    assert not requests.asked
    requests.ask(SetBool.Request(data=False))
    assert requests.asked
    # No service yet: nothing answers, nothing is lost.
    assert not requests.poll()
    assert requests.response is None
    server = PauseServer(ros_context)
    executor.add_node(server.node)
    try:
        assert spin_until(executor, requests.poll)
        assert server.received == [False]
        assert requests.response.message == 'running'
        for _ in range(10):
            executor.spin_once(timeout_sec=RETRY_S / 2)
            assert requests.poll()
        assert server.received == [False]
    finally:
        server.node.destroy_node()


def test_a_lost_request_is_sent_again_until_it_is_answered(ros_context, client_node):
    node, executor = client_node
    client = node.create_client(SetBool, SERVICE)
    requests = AnsweredRequests(client, RETRY_S)
    # The first server takes the request but goes away before it answers: the request is lost.
    first = PauseServer(ros_context, 'first_pause_server')
    assert spin_until(executor, client.service_is_ready)
    requests.ask(SetBool.Request(data=True))
    assert not requests.poll()
    first.node.destroy_node()
    second = PauseServer(ros_context, 'second_pause_server')
    executor.add_node(second.node)
    try:
        assert spin_until(executor, requests.poll)
        assert second.received == [True]
        assert requests.response.message == 'paused'
        assert first.received == []
    finally:
        second.node.destroy_node()


def test_a_newer_request_replaces_the_one_waiting(ros_context, client_node):
    node, executor = client_node
    requests = AnsweredRequests(node.create_client(SetBool, SERVICE), RETRY_S)
    requests.ask(SetBool.Request(data=True))
    requests.ask(SetBool.Request(data=False))
    server = PauseServer(ros_context)
    executor.add_node(server.node)
    try:
        assert spin_until(executor, requests.poll)
        assert server.received == [False]
    finally:
        server.node.destroy_node()


def test_without_a_service_to_ask_every_request_counts_as_answered():
    requests = AnsweredRequests(None)
    requests.ask(SetBool.Request(data=False))
    assert requests.poll()
    assert requests.response is None


def test_the_simulator_pause_is_asked_once_per_change_and_again_until_answered(
        ros_context, client_node):
    node, executor = client_node
    pause = SimulatorPause(node, '/followbot_sim', RETRY_S)
    assert not pause.ready
    pause.ask_paused(True)
    pause.ask_paused(True)
    assert pause.paused is True
    server = PauseServer(ros_context)
    executor.add_node(server.node)
    try:
        assert spin_until(executor, lambda: pause.ready and pause.poll())
        assert server.received == [True]
        # The same wish again is not a new request; a change is, once.
        pause.ask_paused(True)
        for _ in range(5):
            executor.spin_once(timeout_sec=RETRY_S / 2)
            pause.poll()
        assert server.received == [True]
        pause.ask_paused(False)
        pause.ask_paused(False)
        assert spin_until(executor, pause.poll)
        assert server.received == [True, False]
    finally:
        server.node.destroy_node()


def test_without_a_simulator_to_ask_the_pause_is_always_ready_and_answered():
    pause = SimulatorPause(None, None)
    assert pause.ready
    pause.ask_paused(False)
    assert pause.poll()
