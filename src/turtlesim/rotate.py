"""Turning a turtle in place to an absolute heading (pure: no ROS), as ROS 2 turtlesim's RotateAbsolute action
does, for the demo's turtle_actions. ROS 2 turns at 1 rad/s and stops within 0.02 rad of the goal; from a node
beside turtlesim (a pose in, a cmd_vel out, a tick or two late) that speed would overshoot, so the last third of a
radian slows down in proportion to the angle left, which also lets it stop nearer (0.01 rad)."""

import math

MAX_SPEED = 1.0  # rad/s, as ROS 2's turtle turns
MIN_SPEED = 0.15  # rad/s: the slowest, in the last degrees
SLOWING = 3.0  # 1/s: within MAX_SPEED / SLOWING rad of the goal the speed is SLOWING times the angle left
TOLERANCE = 0.01  # rad: nearer than this is there


def normalized(angle):
    """The same angle within [-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def goal_error(theta):
    """Why a goal heading cannot be turned to, or None."""
    if not math.isfinite(theta):
        return f"theta must be a finite number of radians, not {theta}"
    return None


def remaining(goal, heading):
    """The angle (rad) still to turn from heading to goal, the shorter way: positive counter-clockwise."""
    return normalized(goal - heading)


def turn_speed(left):
    """The angular velocity (rad/s) to turn with `left` rad still to go; 0.0 once within TOLERANCE."""
    if abs(left) < TOLERANCE:
        return 0.0
    return math.copysign(min(MAX_SPEED, max(MIN_SPEED, SLOWING * abs(left))), left)


def turned(start, heading):
    """RotateAbsolute's result `delta` as ROS 2 gives it: the starting heading minus the final one, normalized."""
    return normalized(start - heading)
