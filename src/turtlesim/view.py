"""What the window shows: the trail image with a turtle drawn on top per turtle (`compose`, plain PIL), and
the Tk window that displays it (`open_window`). The turtle drawings are never part of the trail image, so
they never reach the colour sensor."""

import functools
import math
import os
import tkinter

from PIL import Image, ImageDraw, ImageTk

from turtlesim.sim import METER, SIZE_PX

TITLE = "TurtleSim"
REFRESH_MS = 30  # how often the window looks for a changed picture (about 33 Hz)


def _ellipse(cx, cy, rx, ry, points=20):
    return [
        (cx + rx * math.cos(2 * math.pi * i / points), cy + ry * math.sin(2 * math.pi * i / points))
        for i in range(points)
    ]


# The turtle, seen from above and heading along +u, as (fill, outline, polygon in pixels; v to its left).
# About 45 px from tail to nose, like the reference's pictures.
_SKIN, _SKIN_EDGE = (140, 200, 90), (60, 100, 40)
_SHELL, _SHELL_EDGE, _SHELL_PLATE = (50, 130, 60), (25, 70, 30), (90, 165, 85)
TURTLE_SHAPES = [
    *[(_SKIN, _SKIN_EDGE, _ellipse(u, v, 5.5, 4)) for u in (-9, 9) for v in (-13, 13)],  # legs
    (_SKIN, _SKIN_EDGE, [(-13, -3), (-22, 0), (-13, 3)]),  # tail
    (_SKIN, _SKIN_EDGE, _ellipse(18, 0, 7.5, 6)),  # head
    ((20, 30, 20), None, _ellipse(21, -3, 1.5, 1.5, 8)),  # eyes
    ((20, 30, 20), None, _ellipse(21, 3, 1.5, 1.5, 8)),
    (_SHELL, _SHELL_EDGE, _ellipse(0, 0, 15, 12.5)),  # shell
    (_SHELL_PLATE, _SHELL_EDGE, _ellipse(0, 0, 6, 6, 6)),  # its middle plate, a hexagon
]


SPRITE_HALF = 28  # px: a turtle picture is a square of twice this, centred on the turtle


@functools.lru_cache(maxsize=360)
def turtle_sprite(degrees):
    """The turtle picture (RGBA, transparent around it) heading `degrees` (whole degrees, 0 = +x, counter-
    clockwise): drawn once per heading, then pasted, which is much faster than drawing every frame."""
    sprite = Image.new("RGBA", (2 * SPRITE_HALF, 2 * SPRITE_HALF), (0, 0, 0, 0))
    draw = ImageDraw.Draw(sprite)
    cos, sin = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    for fill, outline, shape in TURTLE_SHAPES:  # (the picture's y axis points down)
        draw.polygon(
            [(SPRITE_HALF + u * cos - v * sin, SPRITE_HALF - u * sin - v * cos) for u, v in shape],
            fill=fill,
            outline=outline,
        )
    return sprite


def compose(trail, turtles):
    """The picture of the window: a copy of the trail image with every turtle drawn on it."""
    frame = trail.copy()
    for turtle in turtles:
        sprite = turtle_sprite(round(math.degrees(turtle.orient)) % 360)
        # pixel n's centre is at n + 0.5 in the simulation's pixel coordinates
        left = round(turtle.x * METER - 0.5) - SPRITE_HALF
        top = round(turtle.qy * METER - 0.5) - SPRITE_HALF
        frame.paste(sprite, (left, top), sprite)
    return frame


class Window:
    """A fixed 500 x 500 Tk window. It must run in the main thread and only reads snapshots."""

    def __init__(self, root):
        self.root = root
        root.title(TITLE)
        root.resizable(False, False)
        self.photo = ImageTk.PhotoImage(Image.new("RGB", (SIZE_PX, SIZE_PX)))
        label = tkinter.Label(root, image=self.photo, borderwidth=0, highlightthickness=0)
        label.pack()
        self._version = None

    def run(self, snapshot, stopped, on_close):
        """Shows snapshot() = (version, trail, turtles) or None when unchanged, until `stopped` is set or
        the window is closed (which calls on_close)."""

        def refresh():
            if stopped.is_set():
                self.root.destroy()
                return
            picture = snapshot(self._version)
            if picture is not None:
                self._version, trail, turtles = picture
                self.photo.paste(compose(trail, turtles))
            self.root.after(REFRESH_MS, refresh)

        def close():
            on_close()
            self.root.destroy()

        self.root.protocol("WM_DELETE_WINDOW", close)
        refresh()
        self.root.mainloop()


def open_window():
    """The window, or None when there is no display to show it on."""
    if not os.environ.get("DISPLAY"):
        return None
    try:
        root = tkinter.Tk(className=TITLE)
    except tkinter.TclError:
        return None
    return Window(root)
