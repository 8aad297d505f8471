"""
A service request sent again until it is answered.

A client can see its service as ready before DDS has matched both of the service's topics (the
request and the reply are matched one by one): a request sent in that moment is lost and its
future never completes. A run that waits on the answer (a simulator started paused, a video
that needs the simulator's course) would wait for ever, and does so most on a loaded machine.
Only for requests that may arrive twice (set a state, read parameters): a lost answer to a
request that did arrive sends it again.
"""

import time

from std_srvs.srv import SetBool

# Wall seconds before an unanswered request is sent again.
RETRY_S = 1.0
# The simulator's service (relative to its node name) that pauses (true) or runs (false) it.
PAUSE_SERVICE = 'pause'


class AnsweredRequests:
    """Send the latest request to one service, again every ``retry_s``, until it is answered."""

    def __init__(self, client, retry_s: float = RETRY_S):
        """
        Ask through a client.

        :param client: an rclpy client; None when there is no service to ask (every request
            then counts as answered, with no response).
        :param retry_s: wall seconds to wait for an answer before sending the request again.
        """
        self._client = client
        self._retry_s = retry_s
        self._request = None
        self._future = None
        self._sent_s = -float('inf')

    @property
    def asked(self) -> bool:
        """Return whether a request has been made."""
        return self._request is not None

    @property
    def response(self):
        """Return the answer to the latest request, or None while it has none."""
        if self._future is None or not self._future.done():
            return None
        return self._future.result()

    def ask(self, request) -> None:
        """Make a request (replacing any earlier one); :meth:`poll` sends it until answered."""
        self._request = request
        self._forget_sent()
        self.poll()

    def poll(self) -> bool:
        """
        Send the latest request if the service is there and its last copy went unanswered.

        :return: whether the latest request has been answered.
        """
        if self._client is None or self._request is None:
            return True
        if self._future is not None and self._future.done():
            return True
        if time.monotonic() - self._sent_s >= self._retry_s and self._client.service_is_ready():
            self._forget_sent()
            self._future = self._client.call_async(self._request)
            self._sent_s = time.monotonic()
        return False

    def _forget_sent(self) -> None:
        # An answer to a copy given up on is no longer awaited by anyone.
        if self._future is not None and not self._future.done():
            self._client.remove_pending_request(self._future)
        self._future = None
        self._sent_s = -float('inf')


class SimulatorPause:
    """A simulator's pause service, asked once per change of mind and again until answered."""

    def __init__(self, node, simulator_name: str | None, retry_s: float = RETRY_S):
        """
        Make the client.

        :param node: the node the client belongs to.
        :param simulator_name: the simulator's fully qualified node name, such as
            /followbot_sim; None when there is no simulator to ask (every request then counts
            as answered).
        :param retry_s: wall seconds to wait for an answer before asking again.
        """
        self._client = None if simulator_name is None else node.create_client(
            SetBool, f'{simulator_name}/{PAUSE_SERVICE}')
        self._requests = AnsweredRequests(self._client, retry_s)
        # What was asked last: True paused, False running, None nothing yet.
        self.paused = None

    @property
    def ready(self) -> bool:
        """Tell whether the service is there to ask (always, with no simulator to ask)."""
        return self._client is None or self._client.service_is_ready()

    def ask_paused(self, paused: bool) -> None:
        """Ask for the simulator paused or running, unless that is what was asked last."""
        if paused != self.paused:
            self.paused = paused
            self._requests.ask(SetBool.Request(data=paused))

    def poll(self) -> bool:
        """
        Send the latest request again if its last copy went unanswered.

        :return: whether the latest request has been answered.
        """
        return self._requests.poll()
