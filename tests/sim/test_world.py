"""The World's virtual clock: events in time order, activities caught up first, seeded RNGs."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim.world import World


class Recorder:
    def __init__(self, world):
        self.world, self.calls = world, []

    def run_until(self, t):
        self.calls.append(t)


@given(st.lists(st.floats(0, 1e4, allow_nan=False), min_size=1, max_size=30),
       st.floats(0, 2e4, allow_nan=False))
def test_events_fire_in_time_order_and_only_up_to_the_target(times, target):
    world = World(1)
    fired = []
    for t in times:
        world.schedule(t, lambda t=t: fired.append((t, world.now)))
    world.advance_to(target)
    assert [f[0] for f in fired] == sorted(t for t in times if t <= target)
    assert all(now == t for t, now in fired)  # the clock reads the event's time inside it
    assert world.now == target


def test_activities_catch_up_before_each_event_and_never_go_back():
    world = World(0)
    rec = Recorder(world)
    world.add_activity(rec)
    seen = []
    world.schedule(5.0, lambda: seen.append(list(rec.calls)))
    world.advance_to(10.0)
    assert seen == [[5.0]]            # caught up to 5 s before the event ran
    assert rec.calls == [5.0, 10.0]
    assert rec.calls == sorted(rec.calls)


def test_cancelled_event_does_not_fire():
    world = World(0)
    fired = []
    ev = world.schedule(1.0, lambda: fired.append(1))
    World.cancel(ev)
    world.advance(2.0)
    assert fired == []


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), 1e9])
def test_advance_rejects_bad_durations_with_the_value_in_the_message(bad):
    world = World(0)
    with pytest.raises(ValueError, match="advance"):
        world.advance(bad)
    assert world.now == 0.0


def test_scheduling_in_the_past_is_refused():
    world = World(0)
    world.advance(3.0)
    with pytest.raises(ValueError, match="now"):
        world.schedule(1.0, lambda: None)


def test_named_generators_are_reproducible_and_independent():
    a, b = World(42), World(42)
    b.rng("other-model").normal(size=1000)  # another model drawing must not shift this one
    assert np.array_equal(a.rng("accel").normal(size=10), b.rng("accel").normal(size=10))
    assert not np.array_equal(World(43).rng("accel").normal(size=10),
                              World(42).rng("accel").normal(size=10))


@pytest.mark.parametrize("seed", [-1, 2**63, 1.5, "3"])
def test_seed_validation(seed):
    with pytest.raises(ValueError, match="seed"):
        World(seed)
