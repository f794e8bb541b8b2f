"""read_pace.ReadPace: a publisher is read at each message, or once per window while it keeps sending fast."""

from rosbridge.ros_side.read_pace import COALESCE_AFTER, COALESCE_RATE, COALESCE_WINDOW, ReadPace


def reads(pace, start, gap, count, messages=1, more=False):
    """`count` reads `gap` seconds apart from `start`, each bringing `messages`: what after_read answered."""
    return [pace.after_read(start + i * gap, messages, more) for i in range(count)]


def test_a_publisher_at_1_khz_and_below_is_read_at_each_message():
    pace = ReadPace()
    for hz in (10, 100, 1000, COALESCE_RATE * 0.9):
        assert reads(pace, 0.0, 1 / hz, 200) == [None] * 200, hz
    assert not pace.polling


def test_a_publisher_that_keeps_sending_fast_is_read_once_per_window_while_it_does():
    pace = ReadPace()
    gap = 0.1e-3  # 10 kHz, a read for each message
    answers = reads(pace, 0.0, gap, COALESCE_AFTER + 1)
    assert answers == [None] * COALESCE_AFTER + [COALESCE_WINDOW] and pace.polling
    now = COALESCE_AFTER * gap
    for _ in range(100):  # each read brings the window's messages
        now += COALESCE_WINDOW
        assert pace.after_read(now, 10, False) == COALESCE_WINDOW


def test_a_short_burst_is_read_as_it_comes():
    pace = ReadPace()
    for burst in range(20):  # 100 Hz bursts of a few messages, each read on its own
        assert reads(pace, burst * 0.01, 10e-6, COALESCE_AFTER) == [None] * COALESCE_AFTER


def test_reads_that_bring_nothing_complete_do_not_make_a_streak_or_break_one():
    pace = ReadPace()
    answers = []
    for i in range(COALESCE_AFTER + 1):
        answers.append(pace.after_read(i * 0.1e-3, 0, False))  # (a message in two parts)
        answers.append(pace.after_read(i * 0.1e-3 + 10e-6, 1, False))
    assert answers[:-1] == [None] * (2 * COALESCE_AFTER + 1) and answers[-1] == COALESCE_WINDOW


def test_polling_ends_when_the_publisher_slows_down_or_stops_and_starts_again_only_after_a_new_streak():
    for last_read in (1, 0):  # slowed to one message a window, or none
        pace = ReadPace()
        reads(pace, 0.0, 0.1e-3, COALESCE_AFTER + 1)
        assert pace.after_read(0.01, last_read, False) is None and not pace.polling
        assert reads(pace, 0.011, 0.1e-3, COALESCE_AFTER) == [None] * COALESCE_AFTER  # watched again
        assert pace.after_read(0.011 + COALESCE_AFTER * 0.1e-3, 1, False) == COALESCE_WINDOW


def test_more_waiting_is_read_as_it_comes():
    pace = ReadPace()  # a flood that fills every read, or a big message in parts: never polled
    assert reads(pace, 0.0, 10e-6, 100, messages=500, more=True) == [None] * 100
    reads(pace, 1.0, 0.1e-3, COALESCE_AFTER + 1)
    assert pace.polling
    assert pace.after_read(1.1, 500, True) is None and not pace.polling
