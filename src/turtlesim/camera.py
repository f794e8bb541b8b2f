"""The demo camera's picture: an overhead view of the turtle world drawn from the turtles' poses (no ROS), so
that a new user sees the console's camera panel work. Not part of turtlesim's reference interface."""

import math

from PIL import Image, ImageDraw

from turtlesim.sim import DEFAULT_BACKGROUND, WIDTH

TURTLE_COLOURS = [(46, 204, 113), (255, 194, 71), (255, 107, 125), (107, 121, 255), (240, 240, 240)]


def render(poses, size=320):
    """An RGB image of the world: a metre grid, each turtle a disc with a line showing its heading.
    poses: {name: (x, y, theta)} in metres and radians (y up, as turtlesim's)."""
    image = Image.new("RGB", (size, size), DEFAULT_BACKGROUND)
    draw = ImageDraw.Draw(image)
    scale = size / WIDTH
    for metre in range(1, int(WIDTH) + 1):
        at = round(metre * scale)
        draw.line([(at, 0), (at, size)], fill=(88, 104, 255))
        draw.line([(0, size - at), (size, size - at)], fill=(88, 104, 255))
    for index, (_name, (x, y, theta)) in enumerate(sorted(poses.items())):
        cx, cy = x * scale, size - y * scale
        r = max(3.0, 0.35 * scale)
        colour = TURTLE_COLOURS[index % len(TURTLE_COLOURS)]
        draw.ellipse([cx - r, cy - r, cx + r, cy + r], fill=colour)
        draw.line(
            [(cx, cy), (cx + 1.8 * r * math.cos(theta), cy - 1.8 * r * math.sin(theta))],
            fill=(20, 20, 30),
            width=max(1, round(r / 3)),
        )
    return image
