"""The demo laser's ranges: walls and other turtles, in LaserScan's ray order."""

import math
import random
import statistics

import pytest

from turtlesim.laser import RANGE_MIN, TURTLE_RADIUS, add_noise, scan, usable_settings
from turtlesim.sim import HEIGHT, WIDTH


def ray(ranges, angle):
    """The range of the ray at `angle` relative to the heading (angle_min -pi, 2*pi over the rays)."""
    return ranges[round((angle + math.pi) / (2 * math.pi / len(ranges))) % len(ranges)]


def test_walls_seen_from_the_centre_facing_east():
    x, y = WIDTH / 2, HEIGHT / 2
    ranges = scan((x, y, 0.0), [], 360, 20.0)
    assert ray(ranges, 0.0) == pytest.approx(WIDTH - x)
    assert ray(ranges, math.pi / 2) == pytest.approx(HEIGHT - y)
    assert ray(ranges, -math.pi) == pytest.approx(x)
    assert ray(ranges, math.pi / 4) == pytest.approx(math.hypot(WIDTH - x, HEIGHT - y))


def test_the_heading_turns_the_scan():
    ranges = scan((1.0, 5.0, math.pi / 2), [], 360, 20.0)  # facing north, near the west wall
    assert ray(ranges, 0.0) == pytest.approx(HEIGHT - 5.0)
    assert ray(ranges, math.pi / 2) == pytest.approx(1.0)  # to its left: west


def test_another_turtle_in_front_is_seen_at_its_edge_and_hides_the_wall():
    ranges = scan((2.0, 5.0, 0.0), [(6.0, 5.0)], 720, 20.0)
    assert ray(ranges, 0.0) == pytest.approx(4.0 - TURTLE_RADIUS)
    assert ray(ranges, math.pi / 2) == pytest.approx(HEIGHT - 5.0)  # beside it: the wall


def test_beyond_range_max_is_inf_and_a_turtle_it_stands_on_is_not_seen():
    ranges = scan((1.0, 1.0, 0.0), [(1.1, 1.0)], 4, 5.0)
    assert ray(ranges, 0.0) == math.inf  # the east wall is 10 m away
    assert ray(ranges, -math.pi) == pytest.approx(1.0)


def test_noise_moves_finite_ranges_within_the_lasers_limits_and_leaves_inf():
    ranges = [0.06, 3.0, 11.99, math.inf]
    assert add_noise(ranges, 0.0, 12.0, lambda mu, sigma: 1 / 0) == ranges  # no noise: nothing drawn
    assert add_noise(ranges, 0.1, 12.0, lambda mu, sigma: 0.05) == pytest.approx([0.11, 3.05, 12.0, math.inf])
    assert add_noise(ranges, 0.1, 12.0, lambda mu, sigma: -0.05) == pytest.approx([RANGE_MIN, 2.95, 11.94, math.inf])
    spread = add_noise([5.0] * 2000, 0.2, 12.0, random.Random(1).gauss)
    assert statistics.mean(spread) == pytest.approx(5.0, abs=0.02)
    assert statistics.stdev(spread) == pytest.approx(0.2, rel=0.1)


def test_a_setting_that_is_not_a_finite_number_of_its_kind_keeps_its_previous_value():
    previous = {"rate": 10.0, "rays": 360, "range_max": 12.0, "noise": 0.0}
    settings, refused = usable_settings({"rate": math.nan, "rays": 90, "range_max": math.inf, "noise": 0.1}, previous)
    assert settings == {"rate": 10.0, "rays": 90, "range_max": 12.0, "noise": 0.1}
    assert refused == ["rate", "range_max"]
    assert usable_settings(previous, previous) == (previous, [])
    # a double for the integer `rays` (a web form's number): integral ones are taken as ints, fractions refused
    settings, refused = usable_settings({**previous, "rays": 100.5, "rate": 5}, previous)
    assert (settings["rays"], settings["rate"], refused) == (360, 5.0, ["rays"])
    settings, _ = usable_settings({**previous, "rays": 90.0}, previous)
    assert settings["rays"] == 90 and type(settings["rays"]) is int
    for junk in ("90", True, None, [90]):
        assert usable_settings({**previous, "rays": junk}, previous) == (previous, ["rays"])
