"""The per-client budget: a turn every few frames (or bytes), waits beyond the rates, a burst of one second."""

import pytest

from rosbridge.transport.budget import BYTES_PER_TURN, FRAMES_PER_TURN, ClientBudget

from fakes import Clock


def test_unlimited_rates_still_take_turns():
    budget = ClientBudget(0, 0, Clock())
    delays = [budget.after_frame(100) for _ in range(3 * FRAMES_PER_TURN)]
    assert delays.count(0.0) == 3 and set(delays) == {None, 0.0}
    assert delays[FRAMES_PER_TURN - 1] == 0.0


def test_a_turn_ends_early_after_many_bytes():
    budget = ClientBudget(0, 0, Clock())
    assert budget.after_frame(BYTES_PER_TURN - 1) is None
    assert budget.after_frame(1) == 0.0


def test_beyond_the_frame_rate_the_client_waits_for_its_tokens():
    clock = Clock()
    budget = ClientBudget(FRAMES_PER_TURN * 10, 0, clock)  # ten turns a second
    waits = [budget.after_frame(1) for _ in range(FRAMES_PER_TURN * 11)]
    assert all(w in (None, 0.0) for w in waits[: FRAMES_PER_TURN * 10])
    assert waits[-1] == pytest.approx(0.1)  # one turn too many: a tenth of a second to wait
    clock.now += 1.0  # a second later the burst is back (and no more than that)
    assert all(budget.after_frame(1) in (None, 0.0) for _ in range(FRAMES_PER_TURN * 9))


def test_beyond_the_byte_rate_the_wait_fits_the_size():
    budget = ClientBudget(0, BYTES_PER_TURN, Clock())
    assert budget.after_frame(BYTES_PER_TURN) == 0.0
    assert budget.after_frame(BYTES_PER_TURN // 2) is None
    assert budget.after_frame(BYTES_PER_TURN // 2) == pytest.approx(1.0)
