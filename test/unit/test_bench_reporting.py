"""The benches' one table and figure format (bench/reporting.py): what the suite, the bad-link bench and the rover
bench write in bench/README.md."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
import reporting  # noqa: E402


@pytest.mark.parametrize(
    "value, unit, text",
    [
        (None, "ms", "n/a"),
        (float("nan"), "s", "none"),  # measured, and it never came
        (0.953, "%", "95.3%"),
        (0.99971, "%", "99.97%"),  # a loss too small for one decimal still shows
        (1.0, "%", "100.0%"),
        (2.345, "x", "2.35x"),
        (0.0213, "s", "21.3 ms"),  # seconds: in ms below one
        (0.4567, "s", "457 ms"),
        (12.34, "s", "12.3 s"),
        (12.34, "ms", "12.3 ms"),  # a value already in ms stays so
        (16.64, "/s", "16.6/s"),
        (1234.5, "msg/s", "1,234 msg/s"),
        (5.0, "", "5"),
    ],
)
def test_a_figure_is_written_with_its_unit(value, unit, text):
    assert reporting.fmt(value, unit) == text


def test_a_row_gets_its_ratio_its_goal_and_the_other_servers_columns():
    table = reporting.Table({"reference": "rosbridge_server"})
    table.row("rate", 1500.0, "msg/s", "bare server", 2000.0, ">= 0.6x", True, {"reference": 900.0})
    table.row("loss", None, "%", "", None, "", False)
    table.text_row("age", "1 s -> 2 s", "", {})
    assert table.markdown().splitlines() == [
        "| Figure | Bridge | Baseline (same run) | Ratio | Target |  | rosbridge_server (same run) |",
        "|---|---:|---|---:|---|---|---:|",
        "| rate | 1,500 msg/s | bare server: 2,000 msg/s | 0.75x | >= 0.6x | met | 900 msg/s |",
        "| loss | n/a |  |  |  | **missed** |  |",
        "| age | 1 s -> 2 s |  |  |  |  |  |",
    ]
