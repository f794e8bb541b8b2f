"""turtle_teleop_key: drives turtle1 with the arrow keys (spec/turtlesim.md section 5).

`decode` is the whole key map; `main` is the terminal and ROS shell around it."""

import os
import sys
import termios

QUIT = "quit"
# An arrow key arrives as ESC [ A (or ESC O A): ESC and [ / O are ignored and the final letter moves,
# so plain capital A-D act like the arrows too. Values: (linear, angular) before scaling.
MOVES = {ord("A"): (1, 0), ord("B"): (-1, 0), ord("C"): (0, -1), ord("D"): (0, 1)}
BANNER = "Reading from keyboard\n---------------------------\nUse arrow keys to move the turtle. 'q' to quit."
NOT_A_TERMINAL = (
    "turtle_teleop_key: standard input is not a terminal; run it in a terminal to drive the turtle with the arrow keys"
)


def decode(byte):
    """(linear, angular) for a byte that moves the turtle, QUIT for 'q', None for any other byte."""
    if byte == ord("q"):
        return QUIT
    return MOVES.get(byte)


def decode_keys(data):
    """The moves and QUITs in a chunk of terminal input, in order: keys typed (or pasted) quickly arrive
    together in one read, and each one counts."""
    return [key for key in map(decode, data) if key is not None]


def raw_mode(attrs):
    """The reference's keyboard mode: no line editing and no echo, but Ctrl-C still signals; reads
    return every single byte as soon as it is typed."""
    raw = [*attrs[:6], list(attrs[6])]
    raw[3] &= ~(termios.ICANON | termios.ECHO)
    raw[6][termios.VEOL] = 1
    raw[6][termios.VEOF] = 2
    raw[6][termios.VMIN] = 1  # (Linux keeps these apart from VEOL/VEOF)
    raw[6][termios.VTIME] = 0
    return raw


def main():
    if not os.isatty(0):
        print(NOT_A_TERMINAL, file=sys.stderr)
        sys.exit(1)
    try:
        _drive()
    except KeyboardInterrupt:  # Ctrl-C quits like 'q' (the terminal is restored on the way out)
        pass
    sys.exit(0)


def _drive():
    import rospy
    from geometry_msgs.msg import Twist

    rospy.init_node("teleop_turtle", disable_signals=True)
    # Public names (/scale_linear), as the reference: a private ~scale_linear is not read.
    scale_linear = rospy.get_param("scale_linear", 2.0)
    scale_angular = rospy.get_param("scale_angular", 2.0)
    # An unbounded queue (0): rospy's queue of 1 drops all but the last of keys published together, where
    # the reference publishes every key.
    publisher = rospy.Publisher("turtle1/cmd_vel", Twist, queue_size=0)

    saved = termios.tcgetattr(0)
    termios.tcsetattr(0, termios.TCSANOW, raw_mode(saved))
    try:
        print(BANNER, flush=True)
        while True:
            try:
                data = os.read(0, 1024)
            except OSError as error:
                print(f"read():: {error.strerror}", file=sys.stderr)
                return
            for key in decode_keys(data) if data else [QUIT]:  # (end of input: nothing more to read)
                if key == QUIT:
                    return
                linear, angular = key
                twist = Twist()
                twist.linear.x = scale_linear * linear
                twist.angular.z = scale_angular * angular
                publisher.publish(twist)
    finally:
        termios.tcsetattr(0, termios.TCSANOW, saved)
        rospy.signal_shutdown("quit")
