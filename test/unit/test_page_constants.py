"""The page's picture of turtlesim's world (web/world-constants.js) is sim.py's: the same size, first turtle,
background and pen, so the live world on the page is drawn to turtlesim's scale and colours."""

import json

from turtlesim import sim

from harness import REPO


def page_world():
    text = (REPO / "web" / "world-constants.js").read_text()
    return json.loads(text.split("\nexport default ", 1)[1].strip().rstrip(";"))


def test_the_page_draws_turtlesims_world():
    world = page_world()
    assert world["size_m"] == sim.WIDTH == sim.HEIGHT
    assert world["size_px"] == sim.SIZE_PX
    assert tuple(world["background"]) == sim.DEFAULT_BACKGROUND
    assert tuple(world["pen"]) == sim.DEFAULT_PEN
    assert world["pen_width_px"] == sim.DEFAULT_PEN_WIDTH


def test_the_pages_first_turtle_is_where_turtlesim_spawns_it():
    world = sim.World(log=lambda level, text: None)
    world.spawn_first_turtle()
    world.tick(0.0)  # (the first tick only starts the clock)
    [reading] = world.tick(0.016)
    assert reading.name == "turtle1"
    first = page_world()["first_turtle"]
    assert (first["x"], first["y"], first["theta"]) == (reading.pose.x, reading.pose.y, reading.pose.theta)
