"""
A condition that counts only once it has held, without a break, for a while.

DDS matches a publisher and a subscription once on each side, one after the other. A node that
sees its subscription matched to a publisher (``get_publisher_count()``) knows nothing of the
publisher's side: until the publisher's process has heard of the new subscription, what it
publishes does not go there. Seeing the match first is the rule for a subscription created
after its publisher: it matches at once, while its announcement still travels. A run started
the moment its recorder, or its follower, looks connected therefore loses its first messages
on a loaded machine. Waiting until the match has held for a moment gives the other side time.
"""

import time

# Wall seconds a fresh match must hold before a run relies on both sides of it.
MATCH_SETTLE_S = 1.0


class SteadyCondition:
    """Tell whether a condition has held, without a break, for ``hold_s`` of wall time."""

    def __init__(self, hold_s: float = MATCH_SETTLE_S, clock=time.monotonic):
        """
        Start with the condition not held.

        :param hold_s: wall seconds the condition must hold; 0 counts it at once.
        :param clock: returns the wall time in seconds (monotonic).
        """
        self._hold_s = hold_s
        self._clock = clock
        self._since_s = None

    def update(self, holds: bool) -> bool:
        """
        Take the condition's present value.

        :param holds: whether the condition holds now.
        :return: whether it has held since at least ``hold_s`` ago (each break starts over).
        """
        if not holds:
            self._since_s = None
            return False
        now_s = self._clock()
        if self._since_s is None:
            self._since_s = now_s
        return now_s - self._since_s >= self._hold_s
