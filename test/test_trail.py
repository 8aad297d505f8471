"""The path the overview draws: thinned to a centimetre, and bounded in an endless run."""

import tracemalloc

from followbot_sim.trail import Trail


def test_points_nearer_than_the_spacing_are_not_kept():
    trail = Trail(spacing_m=0.01)
    for step in range(100):
        trail.add(step * 0.001, 0.0)
    assert len(trail) == 10
    assert trail.points[0] == (0.0, 0.0)


def test_an_endless_run_keeps_only_the_newest_points():
    trail = Trail(spacing_m=0.01, max_points=500)
    for step in range(10_000):
        trail.add(step * 0.02, 0.0)
    assert len(trail) == 500
    assert trail.points[-1] == (9_999 * 0.02, 0.0)
    assert trail.points[0] == (9_500 * 0.02, 0.0)


def test_clear_forgets_everything():
    trail = Trail()
    trail.add(1.0, 2.0)
    trail.clear()
    assert len(trail) == 0 and trail.points == []


def test_filling_the_trail_takes_no_more_memory():
    # An endless run's simulator keeps flat resident memory (the soak's verdict) from the start.
    trail = Trail(spacing_m=0.01, max_points=20_000)
    tracemalloc.start()
    try:
        before_bytes = tracemalloc.get_traced_memory()[0]
        for step in range(25_000):
            trail.add(step * 0.02, 0.0)
        grown_bytes = tracemalloc.get_traced_memory()[0] - before_bytes
    finally:
        tracemalloc.stop()
    assert len(trail) == 20_000
    assert grown_bytes < 10_000
