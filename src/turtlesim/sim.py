"""The turtlesim world: turtles, their motion and the trail image, as plain Python (no ROS, no GUI).

Coordinates follow the reference: internally x to the right and qy *down* in metres ("Qt" coordinates,
qy = H - y), pixels = metres * METER. The node calls `tick(now)` every 16 ms and publishes what it returns;
service handlers call the other methods. Log lines go to the `log(level, text)` callback given to World,
with level "info", "warn" or "error"; failed requests raise TurtlesimError (after logging, if the reference
logs them)."""

import math
import struct
from collections import namedtuple

from PIL import Image


def float32(value):
    """The value rounded to single precision, where the reference computes in float."""
    return struct.unpack("f", struct.pack("f", value))[0]


PI = 3.14159265  # truncated, as in the reference
METER = 45  # pixels per metre (the height of the reference's turtle image)
SIZE_PX = 500  # the square window and trail image
WIDTH = HEIGHT = float32((SIZE_PX - 1) / METER)  # 11.088889 m
DT = 0.001 * 16  # fixed time step of one tick, whatever the real elapsed time
COMMAND_TIMEOUT = 1.0  # seconds of (wall) time a cmd_vel stays in force
DEFAULT_PEN = (179, 184, 255)
DEFAULT_PEN_WIDTH = 3
UNSET_PEN_WIDTH = 1  # what set_pen width 0 gives (the drawing library's default pen width)
DEFAULT_BACKGROUND = (69, 86, 255)

Pose = namedtuple("Pose", "x y theta linear_velocity angular_velocity")
Reading = namedtuple("Reading", "name pose color")  # what one tick publishes for one turtle
TurtleView = namedtuple("TurtleView", "name x qy orient")  # what the view draws for one turtle


class TurtlesimError(Exception):
    """A request that cannot be served; the message says why."""


class Turtle:
    def __init__(self, name, x, qy, orient):
        self.name = name
        self.x, self.qy, self.orient = x, qy, orient
        self.vx = self.vy = self.wz = 0.0
        self.last_command_time = -math.inf  # a new turtle is at rest
        self.pending_command = None  # (vx, vy, wz) received since the last tick
        self.teleports = []  # callables applied in order at the next tick
        self.pen_on = True
        self.pen_color = DEFAULT_PEN
        self.pen_width = DEFAULT_PEN_WIDTH


class World:
    def __init__(self, log, background=DEFAULT_BACKGROUND):
        self._log = log
        self.trail = Image.new("RGB", (SIZE_PX, SIZE_PX), background)
        self._pixels = self.trail.load()
        self._turtles = {}
        self._id_counter = 0
        self._started = False
        self.version = 0  # goes up whenever the picture (trail or turtles) may have changed

    # ---- queries -------------------------------------------------------------------------------------

    def names(self):
        return sorted(self._turtles)

    def has(self, name):
        return name in self._turtles

    def views(self):
        return [TurtleView(t.name, t.x, t.qy, t.orient) for t in self._sorted()]

    # ---- requests (the ROS services and topics) -------------------------------------------------------

    def spawn(self, x, y, theta, name=""):
        """Adds a turtle at world (x, y) (clamped only at its first tick); returns its name."""
        _require_finite(x=x, y=y, theta=theta)
        if not name:
            name = self._next_free_name()
        elif name in self._turtles:
            self._fail(f"A turtled named [{name}] already exists")  # (sic), the reference's text
        self._turtles[name] = Turtle(name, x, float32(HEIGHT - y), theta)
        self._log("info", "Spawning turtle [%s] at x=[%f], y=[%f], theta=[%f]" % (name, x, y, theta))
        self.version += 1
        return name

    def kill(self, name):
        if name not in self._turtles:
            self._fail(f"Tried to kill turtle [{name}], which does not exist")
        del self._turtles[name]
        self.version += 1

    def command(self, name, vx, vy, wz):
        """A cmd_vel Twist: takes effect at the next tick, and lasts COMMAND_TIMEOUT from then."""
        _require_finite(**{"linear.x": vx, "linear.y": vy, "angular.z": wz})
        self._turtle(name).pending_command = (vx, vy, wz)

    def set_pen(self, name, r, g, b, width, off):
        turtle = self._turtle(name)
        turtle.pen_on = not off
        if off:
            return  # colour and width stay as they were
        turtle.pen_color = (r, g, b)
        turtle.pen_width = width or UNSET_PEN_WIDTH  # not the previous width

    def teleport_absolute(self, name, x, y, theta):
        """Queued for the next tick. x is not clamped there, world y only to <= HEIGHT (as the reference)."""
        _require_finite(x=x, y=y, theta=theta)

        def jump(turtle):
            turtle.x, turtle.qy, turtle.orient = x, max(0.0, HEIGHT - y), theta

        self._turtle(name).teleports.append(jump)

    def teleport_relative(self, name, linear, angular):
        """Queued for the next tick: turn by angular, then move linear along the new heading."""
        _require_finite(linear=linear, angular=angular)

        def jump(turtle):
            turtle.orient += angular
            turtle.x += math.cos(turtle.orient) * linear
            turtle.qy -= math.sin(turtle.orient) * linear

        self._turtle(name).teleports.append(jump)

    def clear(self, background):
        """Fills the trail image with the background colour; turtles are unchanged."""
        self.trail.paste(tuple(background), (0, 0, SIZE_PX, SIZE_PX))
        self.version += 1

    def reset(self, background):
        """Removes every turtle, restarts the naming at turtle1, spawns turtle1 in the centre and clears."""
        self._turtles.clear()
        self._id_counter = 0
        self.spawn_first_turtle()
        self.clear(background)

    def spawn_first_turtle(self):
        return self.spawn(float32(WIDTH / 2.0), float32(HEIGHT / 2.0), 0.0)

    # ---- simulation ----------------------------------------------------------------------------------

    def tick(self, now):
        """One timer tick at (wall) time `now` in seconds: moves every turtle by DT and returns a Reading
        per turtle, alphabetically. The very first tick only starts the clock and returns nothing."""
        if not self._started:
            self._started = True
            return []
        return [self._update(turtle, now) for turtle in self._sorted()]

    def _update(self, t, now):
        for jump in t.teleports:
            old = (t.x, t.qy)
            jump(t)
            if t.pen_on:
                self._stroke(old, (t.x, t.qy), t.pen_color, t.pen_width)
            self.version += 1
        t.teleports.clear()

        if t.pending_command is not None:
            (t.vx, t.vy, t.wz), t.pending_command = t.pending_command, None
            t.last_command_time = now
        if now - t.last_command_time > COMMAND_TIMEOUT:
            t.vx = t.vy = t.wz = 0.0

        old_x, old_qy, old_orient = t.x, t.qy, t.orient
        orient = t.orient + t.wz * DT
        t.orient = orient = orient - 2 * PI * math.floor((orient + PI) / (2 * PI))
        cos, sin = math.cos(orient), math.sin(orient)
        t.x += (cos * t.vx - sin * t.vy) * DT
        t.qy -= (cos * t.vy + sin * t.vx) * DT
        if t.x < 0 or t.x > WIDTH or t.qy < 0 or t.qy > HEIGHT:
            self._log("warn", "Oh no! I hit the wall! (Clamping from [x=%f, y=%f])" % (t.x, t.qy))
            t.x = min(max(t.x, 0.0), WIDTH)
            t.qy = min(max(t.qy, 0.0), HEIGHT)

        pose = Pose(t.x, HEIGHT - t.qy, t.orient, math.sqrt(t.vx * t.vx + t.vy * t.vy), t.wz)
        color = self._color_under(t.x, t.qy)  # before this tick's segment is drawn

        if (t.x, t.qy) != (old_x, old_qy):
            if t.pen_on:
                self._stroke((old_x, old_qy), (t.x, t.qy), t.pen_color, t.pen_width)
            self.version += 1
        elif t.orient != old_orient:
            self.version += 1
        return Reading(t.name, pose, color)

    # ---- trail image ---------------------------------------------------------------------------------

    def _color_under(self, x, qy):
        """The trail pixel at the position rounded to whole pixels."""
        px = min(max(round_half_up(x * METER), 0), SIZE_PX - 1)
        py = min(max(round_half_up(qy * METER), 0), SIZE_PX - 1)
        return self._pixels[px, py]

    def _stroke(self, a, b, color, width):
        """Paints segment a-b (metres) like the reference's aliased painter with a square-capped pen: the
        rectangle of that width, extended by width/2 beyond both ends; a pixel is painted when its centre
        is inside (pixel n spans [n, n+1)). A zero-length segment paints a width x width square.
        A pen of width 1 or less is drawn the way the reference's library draws thin lines instead."""
        if width <= 1:
            self._thin_line(a, b, color)
            return
        ax, ay, bx, by = a[0] * METER, a[1] * METER, b[0] * METER, b[1] * METER
        length = math.hypot(bx - ax, by - ay)
        ux, uy = ((bx - ax) / length, (by - ay) / length) if length else (1.0, 0.0)
        half = width / 2
        ex, ey = ux * half, uy * half  # along the segment
        nx, ny = -ey, ex  # across it
        self._fill_convex(
            [
                (ax - ex + nx, ay - ey + ny),
                (bx + ex + nx, by + ey + ny),
                (bx + ex - nx, by + ey - ny),
                (ax - ex - nx, ay - ey - ny),
            ],
            color,
        )

    def _thin_line(self, a, b, color):
        """A one-pixel line as Qt 5's raster engine draws it with an aliased, square-capped pen of width <= 1
        (its "cosmetic stroker"): one pixel per column (or row, for steep lines) of the major axis, in 1/64
        pixel fixed point, both ends extended by half a pixel; a point when both ends are one. Unlike the
        area rule above it paints the pixel the line ends in (x.5 rounds up), e.g. where the sensor reads."""
        ends = [(math.trunc(x * METER * 64), math.trunc(y * METER * 64)) for x, y in (a, b)]
        if a == b:
            self._paint(round_half_up(a[0] * METER), round_half_up(a[1] * METER), color)
            return
        (x1, y1), (x2, y2) = ends
        steep = abs(x2 - x1) < abs(y2 - y1)
        if steep:  # walk along y: the same rule with the axes swapped
            (x1, y1), (x2, y2) = (y1, x1), (y2, x2)
        if x1 > x2:
            (x1, y1), (x2, y2) = (x2, y2), (x1, y1)
        if x1 == x2:
            return
        slope = _fixed_div(y2 - y1, x2 - x1)  # minor-axis step per pixel, 16.16 fixed point
        x1, x2 = x1 - 32, x2 + 32  # the square caps: half a pixel beyond each end
        minor = (y1 << 10) - (slope >> 1)
        first, end = (x1 + 32) >> 6, (x2 + 32) >> 6
        sample = 32 if slope > 0 else 0  # where in the first pixel the minor axis is taken (Qt 5.15)
        minor += (((first << 6) + sample - x1) * slope) >> 6
        for major in range(first, end):
            self._paint(*((minor >> 16, major) if steep else (major, minor >> 16)), color)
            minor += slope

    def _paint(self, x, y, color):
        if 0 <= x < SIZE_PX and 0 <= y < SIZE_PX:
            self._pixels[x, y] = color

    def _fill_convex(self, corners, color):
        """Scanline fill of a convex polygon in pixel coordinates, sampling pixel centres with the
        half-open (top-left) rule so that adjacent shapes never paint the same pixel twice."""
        ys = [y for _, y in corners]
        first_row = max(0, math.ceil(min(ys) - 0.5))
        last_row = min(SIZE_PX - 1, math.ceil(max(ys) - 0.5) - 1)
        edges = list(zip(corners, corners[1:] + corners[:1]))
        for row in range(first_row, last_row + 1):
            yc = row + 0.5
            crossings = [
                x0 + (yc - y0) * (x1 - x0) / (y1 - y0)
                for (x0, y0), (x1, y1) in edges
                if (y0 <= yc < y1) or (y1 <= yc < y0)
            ]
            if len(crossings) < 2:
                continue
            first_col = max(0, math.ceil(min(crossings) - 0.5))
            last_col = min(SIZE_PX - 1, math.ceil(max(crossings) - 0.5) - 1)
            if first_col <= last_col:
                self.trail.paste(color, (first_col, row, last_col + 1, row + 1))

    # ---- helpers -------------------------------------------------------------------------------------

    def _sorted(self):
        return [self._turtles[name] for name in sorted(self._turtles)]

    def _turtle(self, name):
        try:
            return self._turtles[name]
        except KeyError:
            raise TurtlesimError(f"There is no turtle named [{name}] (it was killed or never spawned)") from None

    def _next_free_name(self):
        while True:
            self._id_counter += 1
            name = f"turtle{self._id_counter}"
            if name not in self._turtles:
                return name

    def _fail(self, text):
        self._log("error", text)
        raise TurtlesimError(text)


def round_half_up(value):
    """Rounds to the nearest integer, halves up (Qt's qRound for positive values)."""
    return math.floor(value + 0.5)


def _fixed_div(numerator, denominator):
    """numerator / denominator in 16.16 fixed point, truncated toward zero like C integer division."""
    quotient = abs(numerator << 16) // abs(denominator)
    return quotient if (numerator < 0) == (denominator < 0) else -quotient


def _require_finite(**values):
    """Infinity or NaN would poison the pose for good; the reference has no answer for them either."""
    bad = [name for name, value in values.items() if not math.isfinite(value)]
    if bad:
        raise TurtlesimError(
            f"{', '.join(bad)} must be a finite number, not {', '.join(str(values[name]) for name in bad)}"
        )
