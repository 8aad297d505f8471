"""A condition counted once it has held for a while: runs wait so before relying on a match."""

from followbot_sim.steady_condition import SteadyCondition
import pytest


class FakeWallClock:
    """A wall clock the test moves by hand."""

    def __init__(self):
        """Start at 100 s."""
        self.now_s = 100.0

    def __call__(self) -> float:
        """Return the time now."""
        return self.now_s


# Each step: (seconds the clock moves first, whether the condition holds, what update says).
HELD_FOR_THE_SETTLE_TIME = [(0.0, True, False), (0.99, True, False), (0.01, True, True)]
A_BREAK_STARTS_OVER = [(0.0, True, False), (0.8, False, False), (0.8, True, False),
                       (0.8, True, False), (0.2, True, True)]
NEVER_HOLDS = [(1.0, False, False)] * 5


@pytest.mark.parametrize('steps', [HELD_FOR_THE_SETTLE_TIME, A_BREAK_STARTS_OVER, NEVER_HOLDS],
                         ids=['held', 'break', 'never'])
def test_a_condition_counts_only_once_it_held_without_a_break_for_the_settle_time(steps):
    clock = FakeWallClock()
    steady = SteadyCondition(1.0, clock)
    for advance_s, holds, expected in steps:
        clock.now_s += advance_s
        assert steady.update(holds) == expected, (clock.now_s, holds)


def test_no_settle_counts_at_once():
    assert SteadyCondition(0.0, FakeWallClock()).update(True)
