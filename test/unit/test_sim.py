"""The simulation core against the numbers of spec/turtlesim.md (sections 1-4)."""

import pytest

from turtlesim.sim import DEFAULT_BACKGROUND, DEFAULT_PEN, DT, HEIGHT, WIDTH, TurtlesimError, World, float32

PEN = DEFAULT_PEN
BACKGROUND = DEFAULT_BACKGROUND


def shown(value):
    """A float32 message field as `rostopic echo`-style 6 decimals."""
    return "%f" % float32(value)


class Sim:
    """A world driven by a simulated clock: ticks every DT seconds; commands arrive between ticks."""

    def __init__(self):
        self.logs = []
        self.world = World(lambda level, text: self.logs.append((level, text)))
        self.world.spawn_first_turtle()
        self.now = 100.0
        self.world.tick(self.now)  # the first tick only starts the clock

    def tick(self, count=1):
        readings = None
        for _ in range(count):
            self.now += DT
            readings = {r.name: r for r in self.world.tick(self.now)}
        return readings

    def pose(self, name="turtle1"):
        return self.tick()[name].pose

    def warnings(self):
        return [text for level, text in self.logs if level == "warn"]


@pytest.fixture
def sim():
    return Sim()


def test_world_size_and_start_pose(sim):
    assert WIDTH == HEIGHT == 11.088889122009277
    pose = sim.pose()
    assert (pose.x, pose.y, pose.theta) == (5.544444561004639, 5.544444561004639, 0.0)
    assert sim.logs == [("info", "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], theta=[0.000000]")]


def test_first_tick_only_starts_the_clock():
    world = World(lambda *_: None)
    world.spawn_first_turtle()
    assert world.tick(0.0) == []
    assert [r.name for r in world.tick(0.016)] == ["turtle1"]


def count_moving_ticks(sim, name="turtle1"):
    """Ticks for 200 ticks; returns how many moved the turtle, and its last pose."""
    moving = 0
    for _ in range(200):
        before = sim.world.views()
        pose = sim.pose(name)
        moving += sim.world.views() != before
    return moving, pose


def test_one_twist_moves_for_63_ticks(sim):
    sim.world.command("turtle1", 2.0, 0.0, 0.0)
    assert sim.pose().linear_velocity == 2.0
    moving, pose = count_moving_ticks(sim)
    assert moving + 1 == 63
    assert shown(pose.x) == "7.560444" and shown(pose.y) == "5.544445"
    assert pose.linear_velocity == 0.0  # stopped by the timeout


def test_one_twist_turns_4_032_rad_wrapped(sim):
    sim.world.command("turtle1", 0.0, 0.0, 4.0)
    _, pose = count_moving_ticks(sim)
    assert shown(pose.theta) == "-2.251185"
    assert shown(pose.x) == "5.544445"


def test_linear_y_is_holonomic_and_speed_is_never_negative(sim):
    sim.world.command("turtle1", 0.0, 1.0, 0.0)
    pose = sim.pose()
    assert pose.y == pytest.approx(5.544444561004639 + DT) and pose.x == 5.544444561004639
    sim.world.command("turtle1", -1.0, 0.0, -0.5)
    pose = sim.pose()
    assert pose.linear_velocity == 1.0 and pose.angular_velocity == -0.5


def test_commands_extend_the_motion(sim):
    sim.world.command("turtle1", 1.0, 0.0, 0.0)
    sim.tick(50)
    sim.world.command("turtle1", 1.0, 0.0, 0.0)
    moving, _ = count_moving_ticks(sim)
    assert moving == 63


def test_spawn_outside_is_clamped_at_the_first_tick_with_the_qt_y_in_the_warning(sim):
    assert sim.world.spawn(20.0, 20.0, float32(4.0), "far") == "far"
    assert ("info", "Spawning turtle [far] at x=[20.000000], y=[20.000000], theta=[4.000000]") in sim.logs
    pose = sim.pose("far")
    assert sim.warnings() == ["Oh no! I hit the wall! (Clamping from [x=20.000000, y=-8.911111])"]
    assert (shown(pose.x), shown(pose.y), shown(pose.theta)) == ("11.088889", "11.088889", "-2.283185")
    sim.tick(5)
    assert len(sim.warnings()) == 1  # at rest inside the walls: no more warnings


def test_pushing_into_a_wall_warns_every_tick_until_the_timeout(sim):
    sim.world.command("turtle1", 0.0, 0.0, 0.0)
    sim.world.teleport_absolute("turtle1", 11.0, 5.0, 0.0)
    sim.tick()
    sim.world.command("turtle1", 2.0, 0.0, 0.0)
    sim.tick(100)
    warnings = sim.warnings()
    assert 55 <= len(warnings) <= 63
    assert all(w.startswith("Oh no! I hit the wall! (Clamping from [x=11.") for w in warnings)
    assert sim.pose().x == WIDTH


def teleport(sim, method, *args):
    getattr(sim.world, method)("turtle1", *args)
    return sim.pose()


@pytest.fixture
def at_1_1_0(sim):
    assert teleport(sim, "teleport_absolute", 1.0, 1.0, 0.0)[:3] == pytest.approx((1.0, 1.0, 0.0))
    sim.logs.clear()
    return sim


def test_teleport_relative_turns_then_moves(at_1_1_0):
    pose = teleport(at_1_1_0, "teleport_relative", 2.0, float32(1.57))
    assert (shown(pose.x), shown(pose.y), shown(pose.theta)) == ("1.001593", "2.999999", "1.570000")


def test_teleport_absolute_theta_is_wrapped_at_the_tick(at_1_1_0):
    assert shown(teleport(at_1_1_0, "teleport_absolute", 5.0, 5.0, float32(4.0)).theta) == "-2.283185"


@pytest.mark.parametrize(
    "x, y, warning, expected",
    [
        (20.0, 20.0, "[x=20.000000, y=0.000000]", (WIDTH, HEIGHT)),
        (-1.0, -1.0, "[x=-1.000000, y=12.088889]", (0.0, 0.0)),
    ],
)
def test_teleport_absolute_outside_is_clamped(at_1_1_0, x, y, warning, expected):
    pose = teleport(at_1_1_0, "teleport_absolute", x, y, 0.0)
    assert at_1_1_0.warnings() == [f"Oh no! I hit the wall! (Clamping from {warning})"]
    assert (pose.x, pose.y) == pytest.approx(expected)
    assert pose.linear_velocity == 0.0


def test_teleports_wait_for_the_next_tick_and_apply_in_order(sim):
    sim.world.teleport_absolute("turtle1", 1.0, 1.0, 0.0)
    sim.world.teleport_relative("turtle1", 1.0, 0.0)
    assert sim.world.views()[0].x == 5.544444561004639
    assert sim.pose()[:2] == pytest.approx((2.0, 1.0))


def test_spawn_names_count_up_and_never_reuse_after_a_kill(sim):
    assert [sim.world.spawn(1.0, 1.0, 0.0) for _ in range(3)] == ["turtle2", "turtle3", "turtle4"]
    sim.world.kill("turtle2")
    assert sim.world.spawn(1.0, 1.0, 0.0) == "turtle5"
    assert sim.world.names() == ["turtle1", "turtle3", "turtle4", "turtle5"]
    assert list(sim.tick()) == ["turtle1", "turtle3", "turtle4", "turtle5"]  # alphabetical


def test_automatic_names_skip_names_in_use(sim):
    sim.world.spawn(1.0, 1.0, 0.0, "turtle2")
    assert sim.world.spawn(1.0, 1.0, 0.0) == "turtle3"


def test_spawning_an_existing_name_fails_and_logs_the_reference_text(sim):
    with pytest.raises(TurtlesimError, match=r"turtle1\] already exists"):
        sim.world.spawn(1.0, 1.0, 0.0, "turtle1")
    assert sim.logs[-1] == ("error", "A turtled named [turtle1] already exists")


def test_killing_an_unknown_turtle_fails_and_logs_the_reference_text(sim):
    with pytest.raises(TurtlesimError, match="which does not exist"):
        sim.world.kill("nobody")
    assert sim.logs[-1] == ("error", "Tried to kill turtle [nobody], which does not exist")


@pytest.mark.parametrize(
    "call, args",
    [
        ("command", (1.0, 0.0, 0.0)),
        ("set_pen", (1, 2, 3, 4, 0)),
        ("teleport_absolute", (1.0, 1.0, 0.0)),
        ("teleport_relative", (1.0, 0.0)),
    ],
)
def test_requests_for_a_killed_turtle_fail_clearly(sim, call, args):
    sim.world.kill("turtle1")
    with pytest.raises(TurtlesimError, match=r"no turtle named \[turtle1\]"):
        getattr(sim.world, call)("turtle1", *args)
    assert sim.tick() == {}


def drive(sim, speed, ticks, name="turtle1"):
    colors = []
    for _ in range(ticks):
        sim.world.command(name, speed, 0.0, 0.0)
        colors.append(sim.tick()[name].color)
    return colors


def test_color_sensor_reads_the_pen_at_rest_after_a_move(sim):
    colors = drive(sim, 1.0, 40)
    assert colors[0] == BACKGROUND  # sampled before the first segment is drawn
    assert sim.tick(70)["turtle1"].color == PEN
    default_pen_readings = colors[1:].count(PEN) / len(colors[1:])
    assert 0.6 < default_pen_readings < 1.0 and set(colors) == {PEN, BACKGROUND}


def test_a_wide_pen_is_read_from_the_second_tick_on(sim):
    sim.world.set_pen("turtle1", 10, 20, 30, 5, 0)
    assert drive(sim, 1.0, 40)[1:] == [(10, 20, 30)] * 39


def test_with_the_pen_off_the_sensor_reads_what_is_under_the_turtle(sim):
    sim.world.set_pen("turtle1", 0, 0, 0, 0, 1)
    assert set(drive(sim, 1.0, 40)) == {BACKGROUND}
    assert sim.world.trail.getcolors() == [(500 * 500, BACKGROUND)]
    sim.world.teleport_relative("turtle1", -0.3, 0.0)  # back along its own (undrawn) path
    assert sim.tick()["turtle1"].color == BACKGROUND


def test_set_pen_off_keeps_colour_and_width_and_width_0_means_1(sim):
    sim.world.set_pen("turtle1", 255, 0, 0, 7, 0)
    sim.world.set_pen("turtle1", 0, 255, 0, 2, 1)
    sim.world.teleport_absolute("turtle1", 1.0, 1.0, 0.0)  # pen off: no line
    sim.tick()
    assert sim.world.trail.getcolors() == [(500 * 500, BACKGROUND)]
    sim.world.set_pen("turtle1", 255, 0, 0, 7, 0)  # back on: the old width and colour still apply
    sim.world.teleport_absolute("turtle1", 3.0, 1.0, 0.0)
    sim.tick()
    red = dict((c, n) for n, c in sim.world.trail.getcolors())[(255, 0, 0)]
    assert red == (90 + 7) * 7  # 2 m * 45 px, square caps of 3.5 px, 7 px wide
    sim.world.set_pen("turtle1", 0, 255, 0, 0, 0)
    sim.world.teleport_absolute("turtle1", 5.0, 1.0, 0.0)
    sim.tick()
    green = dict((c, n) for n, c in sim.world.trail.getcolors())[(0, 255, 0)]
    assert green == 90 + 1


def painted(world, color):
    pixels = world.trail.load()
    return sorted((x, y) for y in range(500) for x in range(500) if pixels[x, y] == color)


def test_a_width_0_pen_ends_its_line_in_the_pixel_the_sensor_reads(sim):
    sim.world.set_pen("turtle1", 0, 0, 0, 0, 1)
    sim.world.teleport_absolute("turtle1", 1.0, 1.0, 0.0)
    sim.tick()
    sim.world.set_pen("turtle1", 0, 255, 0, 0, 0)
    sim.world.teleport_relative("turtle1", 2.0, 0.0)
    assert sim.tick()["turtle1"].color == (0, 255, 0)
    assert painted(sim.world, (0, 255, 0)) == [(x, 454) for x in range(45, 136)]  # as Qt 5.15 paints it


# Pixels Qt 5.15 paints for QPainter.drawLine(new * 45, old * 45) with QPen(QColor) (width 1) on an ARGB32 image
QT_THIN_LINES = [
    (
        (2.0, 2.0),
        (2.3, 1.9),
        [
            (90, 90),
            (91, 89),
            (92, 89),
            (93, 88),
            (94, 88),
            (95, 88),
            (96, 87),
            (97, 87),
            (98, 87),
            (99, 86),
            (100, 86),
            (101, 86),
            (102, 85),
            (103, 85),
        ],
    ),
    ((3.0, 3.0), (3.1, 3.4), [(135 + n // 4, 135 + n) for n in range(19)]),
    ((6.0, 6.0), (6.0, 6.0), [(270, 270)]),
]


@pytest.mark.parametrize("old, new, pixels", QT_THIN_LINES)
def test_thin_lines_are_the_pixels_qt_paints(old, new, pixels):
    world = World(lambda level, text: None)
    world._stroke(old, new, (0, 255, 0), 1)
    assert painted(world, (0, 255, 0)) == pixels


def test_thin_lines_match_qt_itself():
    """Against the reference's drawing library (Debian's PyQt5), on lines in every direction."""
    import random

    qt_gui = pytest.importorskip("PyQt5.QtGui")  # (painting on a QImage needs no QApplication)
    from PyQt5.QtCore import QPointF

    shuffle = random.Random(7)
    for _ in range(40):
        old = (shuffle.uniform(0, WIDTH), shuffle.uniform(0, HEIGHT))
        new = (
            min(max(old[0] + shuffle.uniform(-2, 2), 0), WIDTH),
            min(max(old[1] + shuffle.uniform(-2, 2) * shuffle.choice([0, 0.02, 1]), 0), HEIGHT),
        )
        image = qt_gui.QImage(500, 500, qt_gui.QImage.Format_ARGB32)
        image.fill(qt_gui.qRgb(*BACKGROUND))
        painter = qt_gui.QPainter(image)
        painter.setPen(qt_gui.QPen(qt_gui.QColor(0, 255, 0)))
        painter.drawLine(QPointF(new[0] * 45, new[1] * 45), QPointF(old[0] * 45, old[1] * 45))
        painter.end()
        expected = [(x, y) for y in range(500) for x in range(500) if image.pixel(x, y) & 0xFFFFFF == 0x00FF00]
        world = World(lambda level, text: None)
        world._stroke(old, new, (0, 255, 0), 1)
        assert painted(world, (0, 255, 0)) == sorted(expected), (old, new)


def test_teleport_draws_with_the_pen_across_the_screen(sim):
    sim.world.teleport_absolute("turtle1", 0.5, 0.5, 0.0)
    sim.world.teleport_absolute("turtle1", 10.5, 10.5, 0.0)
    sim.tick()
    trail = sim.world.trail
    assert trail.getpixel((round(5.5 * 45), round((HEIGHT - 5.5) * 45))) == PEN  # on the diagonal
    assert trail.getpixel((round(2 * 45), round((HEIGHT - 8) * 45))) == BACKGROUND


def test_clear_refills_the_background_and_keeps_the_turtles(sim):
    drive(sim, 2.0, 10)
    sim.world.spawn(1.0, 1.0, 0.0)
    sim.world.clear((1, 2, 3))
    assert sim.world.trail.getcolors() == [(500 * 500, (1, 2, 3))]
    assert sim.world.names() == ["turtle1", "turtle2"]
    assert sim.pose().x > 5.6


def test_reset_starts_over_with_turtle1_and_a_clean_trail(sim):
    sim.world.spawn(1.0, 1.0, 0.0)
    sim.world.spawn(1.0, 1.0, 0.0, "bob")
    sim.world.set_pen("turtle1", 1, 1, 1, 1, 1)
    drive(sim, 2.0, 10)
    sim.logs.clear()
    sim.world.reset(BACKGROUND)
    assert sim.logs == [("info", "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], theta=[0.000000]")]
    assert sim.world.names() == ["turtle1"]
    pose = sim.pose()
    assert (pose.x, pose.y, pose.theta, pose.linear_velocity) == (5.544444561004639, 5.544444561004639, 0.0, 0.0)
    assert sim.world.spawn(1.0, 1.0, 0.0) == "turtle2"
    drive(sim, 2.0, 2)
    assert PEN in [c for _, c in sim.world.trail.getcolors()]  # default pen again


def test_version_changes_only_when_the_picture_may_change(sim):
    before = sim.world.version
    sim.tick(3)
    assert sim.world.version == before
    drive(sim, 1.0, 1)
    assert sim.world.version > before


@pytest.mark.parametrize(
    "call, args",
    [
        ("spawn", (float("nan"), 1.0, 0.0)),
        ("command", ("turtle1", float("inf"), 0.0, 0.0)),
        ("teleport_absolute", ("turtle1", 1.0, float("-inf"), 0.0)),
        ("teleport_relative", ("turtle1", float("nan"), 0.0)),
    ],
)
def test_non_finite_numbers_are_refused_and_change_nothing(sim, call, args):
    before = sim.world.views()
    with pytest.raises(TurtlesimError, match="must be a finite number"):
        getattr(sim.world, call)(*args)
    sim.tick()
    assert sim.world.views() == before and sim.world.names() == ["turtle1"]


def test_huge_numbers_end_at_the_walls(sim):
    sim.world.teleport_relative("turtle1", 3e38, 0.5)
    sim.world.command("turtle1", -1e308, 1e308, 1e308)
    pose = sim.pose()
    assert 0 <= pose.x <= WIDTH and 0 <= pose.y <= HEIGHT
