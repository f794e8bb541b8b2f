"""The demo's rotate_absolute action (turtle_actions): the angle left, the turning speed, ROS 2's delta."""

import math

import pytest

from turtlesim.rotate import MAX_SPEED, MIN_SPEED, TOLERANCE, goal_error, normalized, remaining, turn_speed, turned
from turtlesim.sim import DT


def test_the_shorter_way_round():
    assert remaining(math.pi / 2, 0.0) == pytest.approx(math.pi / 2)
    assert remaining(-3.0, 3.0) == pytest.approx(2 * math.pi - 6.0)  # across +-pi: counter-clockwise, 0.28 rad
    assert remaining(7 * math.pi / 2, 0.0) == pytest.approx(-math.pi / 2)  # any heading, modulo 2 pi
    assert normalized(5.0) == pytest.approx(5.0 - 2 * math.pi)


def test_full_speed_far_away_slower_near_and_stopped_within_the_tolerance():
    assert turn_speed(2.0) == MAX_SPEED and turn_speed(-2.0) == -MAX_SPEED
    assert 0 < turn_speed(0.2) < MAX_SPEED and turn_speed(-0.2) == -turn_speed(0.2)
    assert turn_speed(TOLERANCE * 1.5) == MIN_SPEED
    assert turn_speed(TOLERANCE * 0.9) == 0.0 and turn_speed(-TOLERANCE * 0.9) == 0.0


@pytest.mark.parametrize("start,goal", [(0.0, math.pi / 2), (3.0, -3.0), (0.5, -2.5), (-1.0, 1.0 + 4 * math.pi)])
def test_turning_tick_by_tick_reaches_the_goal_even_a_tick_late(start, goal):
    """The node sees each pose and its command applies a tick later (at least): it still ends within TOLERANCE."""
    heading, applied, ticks = start, 0.0, 0
    while True:
        left = remaining(goal, heading)
        speed = turn_speed(left)
        heading, applied = normalized(heading + applied * DT), speed  # last tick's command moves the turtle
        ticks += 1
        if speed == 0.0:
            break
        assert ticks < 400  # no endless hunting: about pi seconds at most
    assert abs(remaining(goal, heading)) < TOLERANCE + MIN_SPEED * DT
    assert turned(start, heading) == pytest.approx(normalized(start - heading))


def test_a_goal_that_is_not_a_number_is_refused_with_the_reason():
    assert goal_error(1.5) is None and goal_error(-100.0) is None
    assert goal_error(math.nan) == "theta must be a finite number of radians, not nan"
    assert "not inf" in goal_error(math.inf)
