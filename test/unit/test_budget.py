"""The per-client budget: a turn every few frames (or bytes), waits beyond the rates, a burst of one second."""

import pytest

from rosbridge.transport.budget import BYTES_PER_TURN, FRAMES_PER_TURN, Carryover, ClientBudget

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


def test_a_client_that_reconnects_starts_with_what_its_address_left_refilled_since():
    clock = Clock()
    carryover = Carryover(0, 10 * BYTES_PER_TURN, clock)
    budget = carryover.budget("10.0.0.1")
    for _ in range(20):  # two seconds' worth at once: ten turns in debt
        budget.after_frame(BYTES_PER_TURN)
    carryover.closed("10.0.0.1", budget)
    clock.now += 0.5  # five turns' worth back: five still owed
    again = carryover.budget("10.0.0.1")
    assert again.after_frame(BYTES_PER_TURN) == pytest.approx(0.6)
    assert carryover.budget("10.0.0.2").after_frame(BYTES_PER_TURN) == 0.0  # another address: a full bucket
    assert len(carryover) == 0  # (taken by the client that came back)


def test_a_bucket_left_full_is_not_remembered_and_the_emptiest_of_two_is_kept():
    clock = Clock()
    carryover = Carryover(0, 10 * BYTES_PER_TURN, clock)
    carryover.closed("a", carryover.budget("a"))
    assert len(carryover) == 0
    first, second = carryover.budget("a"), carryover.budget("a")
    first.after_frame(BYTES_PER_TURN)
    for _ in range(5):
        second.after_frame(BYTES_PER_TURN)
    carryover.closed("a", second)
    carryover.closed("a", first)
    assert carryover.budget("a").after_frame(6 * BYTES_PER_TURN) == pytest.approx(0.1)


def test_at_most_MAX_ADDRESSES_are_remembered_the_oldest_forgotten(monkeypatch):
    monkeypatch.setattr(Carryover, "MAX_ADDRESSES", 3)
    carryover = Carryover(FRAMES_PER_TURN, 0, Clock())
    for address in "abcd":
        budget = carryover.budget(address)
        budget.after_frame(1)
        carryover.closed(address, budget)
    assert len(carryover) == 3
    assert carryover.budget("a").full()  # forgotten: a full bucket
    assert not carryover.budget("d").full()
