"""The per-client budget: turns every few frames, waits beyond the rates, a burst of one second."""
import pytest

from rosbridge.budget import FRAMES_PER_TURN, ClientBudget


class Clock:
    now = 0.0

    def __call__(self):
        return self.now


def test_unlimited_rates_still_take_turns():
    budget = ClientBudget(0, 0, Clock())
    delays = [budget.after_frame(100) for _ in range(3 * FRAMES_PER_TURN)]
    assert delays.count(0.0) == 3 and set(delays) == {None, 0.0}
    assert delays[FRAMES_PER_TURN - 1] == 0.0


def test_beyond_the_frame_rate_the_client_waits_for_its_tokens():
    clock = Clock()
    budget = ClientBudget(100, 0, clock)
    waits = [budget.after_frame(1) for _ in range(101)]
    assert all(w in (None, 0.0) for w in waits[:100])
    assert waits[100] == pytest.approx(0.01)
    clock.now += 1.0  # a second later the burst is back (and no more than that)
    assert all(budget.after_frame(1) in (None, 0.0) for _ in range(99))


def test_beyond_the_byte_rate_the_wait_fits_the_size():
    budget = ClientBudget(0, 1000, Clock())
    assert budget.after_frame(1000) is None
    assert budget.after_frame(500) == pytest.approx(0.5)
