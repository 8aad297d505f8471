"""A condition counted only once it has held for a while: the settle before a run relies on a match."""

from followbot_sim.steady_condition import SteadyCondition


class FakeWallClock:
    """A wall clock the test moves by hand."""

    def __init__(self):
        """Start at 100 s."""
        self.now_s = 100.0

    def __call__(self) -> float:
        """Return the time now."""
        return self.now_s


def test_a_condition_counts_only_after_it_held_for_the_settle_time():
    clock = FakeWallClock()
    steady = SteadyCondition(1.0, clock)
    assert not steady.update(True)
    clock.now_s += 0.99
    assert not steady.update(True)
    clock.now_s += 0.01
    assert steady.update(True)


def test_a_break_starts_the_wait_over():
    clock = FakeWallClock()
    steady = SteadyCondition(1.0, clock)
    steady.update(True)
    clock.now_s += 0.8
    assert not steady.update(False)
    clock.now_s += 0.8
    assert not steady.update(True)
    clock.now_s += 0.8
    assert not steady.update(True)
    clock.now_s += 0.2
    assert steady.update(True)


def test_a_condition_that_does_not_hold_never_counts():
    clock = FakeWallClock()
    steady = SteadyCondition(0.5, clock)
    for _ in range(5):
        clock.now_s += 1.0
        assert not steady.update(False)


def test_no_settle_counts_at_once():
    assert SteadyCondition(0.0, FakeWallClock()).update(True)
