"""A simulated planar laser for the demo (pure: no ROS): the distances from one turtle to the walls of the
world and to the other turtles (discs of TURTLE_RADIUS), one per ray, counter-clockwise from `angle_min`
relative to the turtle's heading, as sensor_msgs/LaserScan orders them."""

import math

from turtlesim.sim import HEIGHT, WIDTH

TURTLE_RADIUS = 0.45  # m: about the turtle picture's half width
RANGE_MIN = 0.05  # m: nearer than this a laser reads nothing


def scan(pose, others, rays, range_max, angle_min=-math.pi):
    """Ranges (m) from pose (x, y, theta) over `rays` rays spanning 2*pi; inf beyond range_max (REP 117)."""
    x, y, theta = pose
    step = 2 * math.pi / rays
    ranges = []
    for i in range(rays):
        angle = theta + angle_min + i * step
        dx, dy = math.cos(angle), math.sin(angle)
        hit = min(_to_walls(x, y, dx, dy), *(_to_disc(x, y, dx, dy, ox, oy) for ox, oy in others), math.inf)
        ranges.append(hit if hit <= range_max else math.inf)
    return ranges


def add_noise(ranges, sigma, range_max, gauss):
    """Each finite range plus Gaussian noise of standard deviation sigma (m) drawn by gauss(mu, sigma) (e.g.
    random.Random().gauss), kept within [RANGE_MIN, range_max] as a real laser's readings are; inf stays inf."""
    if sigma <= 0:
        return list(ranges)
    return [r if math.isinf(r) else min(range_max, max(RANGE_MIN, r + gauss(0.0, sigma))) for r in ranges]


def usable_settings(requested, previous):
    """The settings to run with, and the names of those refused. dynamic_reconfigure's Server clamps each value to
    its range, but NaN compares false with both ends and passes, and a value comes with the type its sender gave
    it (a double named `rays` from a web page's form passes the clamp). A value that is not a finite number of the
    previous value's kind keeps the previous one; an integral double for an integer setting is taken as an int."""
    settings, refused = dict(requested), []
    for name, value in requested.items():
        kind = type(previous[name])
        usable = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        if usable and kind is int and value != int(value):
            usable = False
        if usable:
            settings[name] = kind(value)
        else:
            settings[name] = previous[name]
            refused.append(name)
    return settings, refused


def _to_walls(x, y, dx, dy):
    """Distance along (dx, dy) from inside the box [0, WIDTH] x [0, HEIGHT] to its edge."""
    hits = []
    if dx > 1e-12:
        hits.append((WIDTH - x) / dx)
    elif dx < -1e-12:
        hits.append(-x / dx)
    if dy > 1e-12:
        hits.append((HEIGHT - y) / dy)
    elif dy < -1e-12:
        hits.append(-y / dy)
    return max(0.0, min(hits))


def _to_disc(x, y, dx, dy, cx, cy):
    """Distance along the unit ray (dx, dy) to the disc around (cx, cy), or inf if the ray misses it (or starts
    inside it: a turtle does not see one it stands on)."""
    ox, oy = cx - x, cy - y
    along = ox * dx + oy * dy
    off2 = ox * ox + oy * oy - along * along
    if along <= 0 or off2 > TURTLE_RADIUS**2 or ox * ox + oy * oy <= TURTLE_RADIUS**2:
        return math.inf
    return along - math.sqrt(TURTLE_RADIUS**2 - off2)
