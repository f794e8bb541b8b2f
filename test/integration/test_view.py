"""The turtlesim window on a virtual X server (Xvfb): its title and size, what it shows (SIGUSR1 snapshot
and a grab of the real X screen) and that it goes away with the node."""

import ctypes
import ctypes.util
import os
import re
import signal
import time

import pytest
from PIL import Image, ImageGrab

from harness import ARTIFACTS, wait_for

BACKGROUND = (69, 86, 255)
PEN = (179, 184, 255)


@pytest.fixture(scope="module")
def display(ros):
    xvfb, name = ros.start_xvfb()
    yield name
    xvfb.stop()


@pytest.fixture
def windowed(start_turtlesim, display, tmp_path):
    snapshot = tmp_path / "snapshot.png"
    proc = start_turtlesim(env={"DISPLAY": display, "TURTLESIM_SNAPSHOT": str(snapshot)})
    geometry = wait_for(lambda: window_geometry(display), 20, what="the TurtleSim window")
    return proc, snapshot, geometry


def window_geometry(display):
    """(x, y, width, height) of the window titled TurtleSim, or None (also while it is still 1x1: Tk maps a
    window before it gives it its size, and a busy machine lets a test look in between)."""
    res = os.popen(f"DISPLAY={display} xwininfo -name TurtleSim 2>/dev/null").read()
    values = dict(re.findall(r"^\s*(Absolute upper-left X|Absolute upper-left Y|Width|Height):\s+(-?\d+)", res, re.M))
    if len(values) < 4 or (values["Width"], values["Height"]) == ("1", "1"):
        return None
    return tuple(int(values[k]) for k in ("Absolute upper-left X", "Absolute upper-left Y", "Width", "Height"))


class ClientMessage(ctypes.Structure):
    _fields_ = [
        ("type", ctypes.c_int),
        ("serial", ctypes.c_ulong),
        ("send_event", ctypes.c_int),
        ("display", ctypes.c_void_p),
        ("window", ctypes.c_ulong),
        ("message_type", ctypes.c_ulong),
        ("format", ctypes.c_int),
        ("data", ctypes.c_long * 5),
        ("padding", ctypes.c_long * 12),
    ]


def close_window(display, title):
    """What a window manager does when the user clicks the close button: a WM_DELETE_WINDOW message."""
    window_id = int(
        re.search(r"Window id: (0x[0-9a-f]+)", os.popen(f"DISPLAY={display} xwininfo -name {title}").read()).group(1),
        16,
    )
    xlib = ctypes.CDLL(ctypes.util.find_library("X11"))
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XInternAtom.restype = ctypes.c_ulong
    xlib.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    xlib.XSendEvent.argtypes = [
        ctypes.c_void_p,
        ctypes.c_ulong,
        ctypes.c_int,
        ctypes.c_long,
        ctypes.POINTER(ClientMessage),
    ]
    xlib.XFlush.argtypes = xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    connection = xlib.XOpenDisplay(display.encode())
    assert connection, f"cannot open display {display}"
    try:
        event = ClientMessage(
            type=33,
            window=window_id,
            format=32,  # 33: ClientMessage
            message_type=xlib.XInternAtom(connection, b"WM_PROTOCOLS", 0),
        )
        event.data[0] = xlib.XInternAtom(connection, b"WM_DELETE_WINDOW", 0)
        assert xlib.XSendEvent(connection, window_id, 0, 0, ctypes.byref(event))
        xlib.XFlush(connection)
    finally:
        xlib.XCloseDisplay(connection)


def take_snapshot(proc, path):
    if path.exists():
        path.unlink()
    proc.signal(signal.SIGUSR1)
    return wait_for(lambda: path.exists() and _load(path), 10, what="the snapshot PNG")


def _load(path):
    try:
        with Image.open(path) as image:
            return image.convert("RGB")
    except OSError:  # still being written
        return None


def drive_in_an_arc(rospy):
    from geometry_msgs.msg import Twist

    from turtlesim.msg import Pose

    publisher = rospy.Publisher("/turtle1/cmd_vel", Twist, queue_size=1)
    wait_for(lambda: publisher.get_num_connections() > 0, 10, what="the cmd_vel connection")
    twist = Twist()
    twist.linear.x, twist.angular.z = 2.0, 1.0
    publisher.publish(twist)
    wait_for(lambda: rospy.wait_for_message("/turtle1/pose", Pose, 10).linear_velocity > 0, 10, what="motion")
    wait_for(lambda: rospy.wait_for_message("/turtle1/pose", Pose, 10).linear_velocity == 0, 10, what="rest")
    publisher.unregister()
    return rospy.wait_for_message("/turtle1/pose", Pose, 10)


def count(image, color):
    return dict((c, n) for n, c in image.getcolors(500 * 500)).get(color, 0)


def test_the_window_is_titled_turtlesim_and_500_by_500(windowed):
    _, _, geometry = windowed
    assert geometry[2:] == (500, 500)


def test_the_window_shows_the_trail_and_the_turtles(windowed, display, node):
    from turtlesim.srv import Spawn

    proc, snapshot_path, (left, top, _, _) = windowed
    node.ServiceProxy("/spawn", Spawn)(2.0, 2.0, 0.0, "")
    pose = drive_in_an_arc(node)

    snapshot = take_snapshot(proc, snapshot_path)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    snapshot.save(ARTIFACTS / "turtlesim_window_snapshot.png")
    assert snapshot.size == (500, 500)
    assert count(snapshot, BACKGROUND) > 200_000
    assert count(snapshot, PEN) > 100  # about 2 m of a 3 px trail, partly under the turtle
    # The turtle is drawn on the pose, and only there: neither the background nor the trail colour.
    px, py = round(pose.x * 45), round((11.088889122009277 - pose.y) * 45)
    around = snapshot.crop((px - 7, py - 7, px + 8, py + 8))  # inside the shell
    assert count(around, BACKGROUND) + count(around, PEN) == 0
    assert snapshot.getpixel((round(2 * 45), round((11.088889 - 2) * 45))) not in (BACKGROUND, PEN)  # turtle2

    def screen_matches():
        grab = ImageGrab.grab(xdisplay=display).crop((left, top, left + 500, top + 500)).convert("RGB")
        return grab if list(grab.getdata()) == list(snapshot.getdata()) else None

    grab = wait_for(screen_matches, 10, what="the X screen to show the snapshot")
    grab.save(ARTIFACTS / "turtlesim_window_screen.png")


def test_rosnode_kill_closes_the_window_and_exits(ros, windowed, display):
    proc, _, _ = windowed
    ros.run(["rosnode", "kill", "/turtlesim"])
    wait_for(lambda: not proc.alive(), 15, what="turtlesim_node to exit")
    assert window_geometry(display) is None


def test_closing_the_window_ends_the_node(ros, windowed, display):
    proc, _, _ = windowed
    close_window(display, "TurtleSim")
    wait_for(lambda: not proc.alive(), 15, what="turtlesim_node to exit")
    wait_for(
        lambda: "/turtlesim" not in ros.run(["rosnode", "list"]).stdout.split(), 10, what="/turtlesim to unregister"
    )


def test_with_a_window_only_the_startup_lines_are_logged(windowed):
    proc, _, _ = windowed
    time.sleep(1)
    assert len([line for line in proc.output().splitlines() if line.startswith("[")]) == 2
