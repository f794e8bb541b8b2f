"""turtle_teleop_key as a real process reading a pseudo-terminal, checked with a rospy subscriber."""

import os
import queue
import signal
import termios

import pytest

from harness import wait_for, wait_publisher_connected

BANNER = "Reading from keyboard\n---------------------------\nUse arrow keys to move the turtle. 'q' to quit.\n"


@pytest.fixture
def twists(node):
    """A queue of the Twists published on /turtle1/cmd_vel, and the subscriber filling it."""
    from geometry_msgs.msg import Twist

    received = queue.Queue()
    subscriber = node.Subscriber("/turtle1/cmd_vel", Twist, received.put)
    yield received, subscriber
    subscriber.unregister()


@pytest.fixture
def pty():
    controller, terminal = os.openpty()
    yield controller, terminal
    os.close(controller)
    os.close(terminal)


@pytest.fixture
def scale_params(ros):
    yield lambda name, value: ros.run(["rosparam", "set", name, str(value)])
    for name in ("/scale_linear", "/scale_angular", "/teleop_turtle/scale_linear"):
        ros.run(["rosparam", "delete", name], check=False)


def start_teleop(ros, terminal, twists):
    """Starts the teleop and waits until it is connected to the `twists` subscriber (this process's node)."""
    proc = ros.spawn(["rosrun", "turtlesim", "turtle_teleop_key"], "teleop", stdin=terminal)
    proc.wait_output(BANNER, timeout=30)
    import rospy

    wait_publisher_connected(ros, "/teleop_turtle", "/turtle1/cmd_vel", rospy.get_name())
    return proc


def press(controller, keys, received):
    os.write(controller, keys)
    twist = received.get(timeout=10)
    return (twist.linear.x, twist.linear.y, twist.linear.z), (twist.angular.x, twist.angular.y, twist.angular.z)


def test_arrow_keys_publish_twists_and_q_quits_restoring_the_terminal(ros, pty, twists):
    controller, terminal = pty
    cooked = termios.tcgetattr(terminal)
    proc = start_teleop(ros, terminal, twists)
    raw = termios.tcgetattr(terminal)
    assert raw[3] & (termios.ICANON | termios.ECHO) == 0 and raw[3] & termios.ISIG
    received = twists[0]
    assert press(controller, b"\x1b[A", received) == ((2.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert press(controller, b"\x1b[B", received) == ((-2.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert press(controller, b"\x1bOD", received) == ((0.0, 0.0, 0.0), (0.0, 0.0, 2.0))
    assert press(controller, b"xyzC", received) == ((0.0, 0.0, 0.0), (0.0, 0.0, -2.0))
    os.write(controller, b"q")
    wait_for(lambda: not proc.alive(), 10, what="teleop to quit")
    assert proc.popen.returncode == 0
    assert termios.tcgetattr(terminal) == cooked
    assert received.empty()
    assert proc.output() == BANNER  # and nothing else


def test_public_scale_parameters_are_honoured_and_private_ones_ignored(ros, pty, twists, scale_params):
    scale_params("/scale_linear", 0.5)
    scale_params("/scale_angular", 3.0)
    scale_params("/teleop_turtle/scale_linear", 9.0)
    controller, terminal = pty
    start_teleop(ros, terminal, twists)
    assert press(controller, b"\x1b[A", twists[0])[0] == (0.5, 0.0, 0.0)
    assert press(controller, b"\x1b[D", twists[0])[1] == (0.0, 0.0, 3.0)


def test_ctrl_c_quits_with_0_and_restores_the_terminal(ros, pty, twists):
    controller, terminal = pty
    cooked = termios.tcgetattr(terminal)
    proc = start_teleop(ros, terminal, twists)
    proc.signal(signal.SIGINT)
    wait_for(lambda: not proc.alive(), 10, what="teleop to quit")
    assert proc.popen.returncode == 0
    assert termios.tcgetattr(terminal) == cooked
    assert "Traceback" not in proc.output()


def test_without_a_terminal_it_says_so_and_exits_1(ros):
    res = ros.run(["rosrun", "turtlesim", "turtle_teleop_key"], check=False, input="")
    assert res.returncode == 1
    assert res.stderr.strip() == (
        "turtle_teleop_key: standard input is not a terminal; "
        "run it in a terminal to drive the turtle with the arrow keys"
    )
    assert res.stdout == ""


def test_keys_arriving_together_publish_one_twist_each(ros, pty, twists):
    controller, terminal = pty
    start_teleop(ros, terminal, twists)
    received = twists[0]

    def moves(count):
        return [(twist.linear.x, twist.angular.z) for twist in (received.get(timeout=10) for _ in range(count))]

    os.write(controller, b"\x1b[A\x1b[A")  # two keys in one write: the teleop reads them together
    assert moves(2) == [(2.0, 0.0), (2.0, 0.0)]
    os.write(controller, b"\x1b[A" * 1000 + b"\x1b[D")  # a burst: rospy must not drop any
    assert moves(1001) == [(2.0, 0.0)] * 1000 + [(0.0, 2.0)]
