"""The teleop key map and terminal mode (spec/turtlesim.md section 5)."""

import termios

import pytest

from turtlesim.teleop import BANNER, QUIT, decode, decode_keys, raw_mode


@pytest.mark.parametrize(
    "byte, expected", [(0x41, (1, 0)), (0x42, (-1, 0)), (0x43, (0, -1)), (0x44, (0, 1)), (0x71, QUIT)]
)
def test_the_four_letters_move_and_q_quits(byte, expected):
    assert decode(byte) == expected


@pytest.mark.parametrize("sequence", [b"\x1b[A", b"\x1bOA", b"A"])
def test_an_arrow_key_is_one_move_whatever_its_prefix(sequence):
    assert [decode(b) for b in sequence if decode(b) is not None] == [(1, 0)]


def test_every_other_byte_is_ignored():
    assert [b for b in range(256) if decode(b) is not None] == [0x41, 0x42, 0x43, 0x44, 0x71]


def test_keys_read_together_each_count_in_order_up_to_quit():
    assert decode_keys(b"\x1b[A\x1b[A") == [(1, 0), (1, 0)]
    assert decode_keys(b"\x1bOD\x1b[Bx\x1b[Cq\x1b[A") == [(0, 1), (-1, 0), (0, -1), QUIT, (1, 0)]
    assert decode_keys(b"") == []


def test_raw_mode_keeps_signals_and_reads_single_bytes():
    cooked = [
        termios.ICRNL,
        termios.OPOST,
        termios.CS8,
        termios.ICANON | termios.ECHO | termios.ISIG,
        termios.B38400,
        termios.B38400,
        [b"\x00"] * termios.NCCS,
    ]
    raw = raw_mode(cooked)
    assert raw[3] == termios.ISIG
    assert raw[:3] == cooked[:3]
    assert (raw[6][termios.VEOL], raw[6][termios.VEOF]) == (1, 2)
    assert (raw[6][termios.VMIN], raw[6][termios.VTIME]) == (1, 0)
    assert cooked[6] == [b"\x00"] * termios.NCCS  # the saved attributes are left alone


def test_banner():
    assert BANNER.splitlines() == [
        "Reading from keyboard",
        "---------------------------",
        "Use arrow keys to move the turtle. 'q' to quit.",
    ]
