"""write_turns.WriteTurns: woken clients write together, at the end of a delivery or in the loop's next turn."""

from rosbridge.transport.write_turns import WriteTurns

from fakes import Loop


def test_outside_a_delivery_the_woken_write_in_the_next_turn_once_for_all():
    loop, written = Loop(), []
    turns = WriteTurns(loop.call_soon)
    turns.wake(lambda: written.append("a"))
    turns.wake(lambda: written.append("b"))
    assert written == [] and len(loop.soon) == 1
    loop.next_turn()
    assert written == ["a", "b"] and loop.soon == []


def test_a_delivery_writes_when_it_ends_in_the_same_turn_and_asks_for_no_other():
    loop, written = Loop(), []
    turns = WriteTurns(loop.call_soon)
    with turns:
        with turns:  # (a delivery inside a delivery: written once the outer one ends)
            turns.wake(lambda: written.append("a"))
        assert written == []
        turns.wake(lambda: written.append("b"))
        assert written == []
    assert written == ["a", "b"] and loop.soon == []


def test_woken_before_a_delivery_writes_with_it_and_the_turn_asked_for_finds_nothing():
    loop, written = Loop(), []
    turns = WriteTurns(loop.call_soon)
    turns.wake(lambda: written.append("status"))
    with turns:
        turns.wake(lambda: written.append("message"))
    assert written == ["status", "message"]
    loop.next_turn()
    assert written == ["status", "message"]


def test_a_write_that_wakes_another_client_and_a_failing_write_do_not_stop_the_others(caplog):
    loop, written = Loop(), []
    turns = WriteTurns(loop.call_soon)

    def fails():
        raise RuntimeError("a bug")

    turns.wake(lambda: turns.wake(lambda: written.append("woken by a write")))
    turns.wake(fails)
    turns.wake(lambda: written.append("after the bug"))
    loop.next_turn()
    assert written == ["after the bug", "woken by a write"]
    assert "a bug" in caplog.text
