"""The window's picture: the trail with the turtles drawn on a copy of it, their heads where they head."""

import pytest
from PIL import Image

from turtlesim.sim import DEFAULT_BACKGROUND, METER, TurtleView
from turtlesim.view import SPRITE_HALF, compose, turtle_sprite

HEAD_DISTANCE = 18  # px from the centre to the middle of the head


def is_turtle(color):
    return color[:3] != DEFAULT_BACKGROUND


def test_compose_draws_on_a_copy_and_leaves_the_trail_alone():
    trail = Image.new("RGB", (500, 500), DEFAULT_BACKGROUND)
    frame = compose(trail, [TurtleView("turtle1", 5.0, 5.0, 0.0)])
    assert trail.getcolors() == [(500 * 500, DEFAULT_BACKGROUND)]
    assert is_turtle(frame.getpixel((round(5.0 * METER), round(5.0 * METER))))
    assert not is_turtle(frame.getpixel((round(5.0 * METER) + 40, round(5.0 * METER))))


@pytest.mark.parametrize(
    "degrees, head, tail_side",
    [
        (0, (HEAD_DISTANCE, 0), (-HEAD_DISTANCE - 6, 0)),  # heading +x: head to the right
        (90, (0, -HEAD_DISTANCE), (0, HEAD_DISTANCE + 6)),  # heading +y (up on the screen)
        (180, (-HEAD_DISTANCE, 0), (HEAD_DISTANCE + 6, 0)),
    ],
)
def test_the_head_is_where_the_turtle_heads(degrees, head, tail_side):
    sprite = turtle_sprite(degrees)
    at = lambda offset: sprite.getpixel((SPRITE_HALF + offset[0], SPRITE_HALF + offset[1]))
    assert at(head)[3] == 255 and at(head)[:3] == (140, 200, 90)  # the head's skin
    assert at(tail_side)[3] == 0  # nothing that far behind (only the thin tail)


def test_a_turtle_is_about_45_px_long():
    alpha = turtle_sprite(0).getchannel("A")
    left, _, right, _ = alpha.getbbox()
    assert 42 <= right - left <= 52
