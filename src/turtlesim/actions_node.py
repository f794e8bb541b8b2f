"""The demo action node (`rosrun turtlesim turtle_actions`): for every turtle, the action server
/<turtle>/rotate_absolute of type turtlesim/RotateAbsolute (action/RotateAbsolute.action), as ROS 2 turtlesim offers
it: the goal `theta` (rad) is the heading to reach; the turtle turns in place the shorter way (rotate.py), by
publishing /<turtle>/cmd_vel while watching /<turtle>/pose; feedback `remaining` (rad) comes with every pose, the
result `delta` is ROS 2's (the starting heading minus the final one). Something for the console's Actions tab with
turtlesim alone; turtlesim_node itself keeps the reference noetic interface, which has no actions. (No action type
Debian ships fits: actionlib's own test actions carry int32s; ROS 2's has the fields a turtle wants, and its name.)

A goal ends succeeded within rotate.TOLERANCE of its heading; preempted on a cancel or a newer goal (actionlib's
SimpleActionServer); aborted, with the reason in its status text, when theta is not a finite number, when another
node drives the turtle (a cmd_vel that is not ours: the teleop, the page; ROS 2 aborts too), or when no pose came
for POSE_TIMEOUT s (turtlesim stopped, the turtle killed). One loop at turtlesim's tick decides everything; the
servers (in polling mode, no execute thread) and the subscribers only leave flags for it."""

import time

import rospy
from actionlib import SimpleActionServer
from geometry_msgs.msg import Twist, Vector3

from turtlesim.msg import RotateAbsoluteAction, RotateAbsoluteFeedback, RotateAbsoluteResult
from turtlesim.pose_watch import PoseWatch
from turtlesim.rotate import goal_error, remaining, turn_speed, turned
from turtlesim.sim import DT

POSE_TIMEOUT = 1.0  # s without a pose before a goal is aborted


class Rotator:
    """One turtle's rotate_absolute server and its goal."""

    def __init__(self, name):
        self.name, self.goal, self.start, self.seen, self.driver = name, None, None, None, None
        self.cmd_vel = rospy.Publisher(f"/{name}/cmd_vel", Twist, queue_size=1)
        self.drivers = rospy.Subscriber(f"/{name}/cmd_vel", Twist, self.driven, queue_size=10)
        self.server = SimpleActionServer(f"/{name}/rotate_absolute", RotateAbsoluteAction, auto_start=False)
        self.server.start()

    def driven(self, twist):
        """A cmd_vel (on a subscriber thread): one from another node takes the turtle over."""
        caller = getattr(twist, "_connection_header", {}).get("callerid")  # rospy sets it on what it receives
        if caller != rospy.get_name():
            self.driver = caller

    def step(self, latest, now):
        """One tick: takes a new goal, then moves the active one on with the latest (pose, arrival time), if new."""
        server = self.server
        if server.is_new_goal_available():  # (a goal still running is preempted by actionlib)
            self.begin(server.accept_new_goal().theta)
        if server.is_active() and goal_error(self.goal):
            self.end(server.set_aborted, None, goal_error(self.goal), halt=False)
        if not server.is_active():
            return
        pose = latest[0] if latest and now - latest[1] <= POSE_TIMEOUT else None
        if server.is_preempt_requested():
            self.end(server.set_preempted, pose, "cancelled" + (f" at {pose.theta:.3f} rad" if pose else ""))
        elif self.driver is not None:
            self.end(server.set_aborted, pose, f"{self.driver} drove {self.name}: goal aborted", halt=False)
        elif pose is None:
            self.end(server.set_aborted, pose, f"no pose from /{self.name}/pose for {POSE_TIMEOUT:g} s: goal aborted")
        elif latest[1] != self.seen:
            self.seen = latest[1]
            if self.start is None:
                self.start = pose.theta
            left = remaining(self.goal, pose.theta)
            server.publish_feedback(RotateAbsoluteFeedback(remaining=left))
            speed = turn_speed(left)
            if speed:
                self.cmd_vel.publish(Twist(angular=Vector3(z=speed)))
            else:
                self.end(server.set_succeeded, pose, f"reached {pose.theta:.3f} rad (goal {self.goal:.3f})")

    def begin(self, theta):
        self.goal, self.start, self.seen, self.driver = theta, None, None, None
        rospy.loginfo("%s: a goal: rotate to %s rad", self.name, theta)

    def end(self, finish, pose, text, halt=True):
        """Ends the goal with finish(result, text) (set_succeeded, set_preempted, set_aborted), the turtle stopped."""
        if halt:
            self.cmd_vel.publish(Twist())
        delta = turned(self.start, pose.theta) if pose is not None and self.start is not None else 0.0
        finish(RotateAbsoluteResult(delta=delta), text)
        (rospy.loginfo if finish == self.server.set_succeeded else rospy.logwarn)("%s: %s", self.name, text)

    def close(self, text):
        """The turtle is gone: its goal aborted, its server and topics closed."""
        if self.server.is_active():
            self.server.set_aborted(RotateAbsoluteResult(), text)
        self.server.action_server.stop()
        self.drivers.unregister()
        self.cmd_vel.unregister()


def main():
    rospy.init_node("turtle_actions")
    latest = {}  # turtle name -> (its latest pose, when it came)
    watch = PoseWatch(lambda name, pose: latest.__setitem__(name, (pose, time.monotonic())))
    rotators = {}
    rate = rospy.Rate(1.0 / DT)
    while not rospy.is_shutdown():
        turtles = dict(watch.poses)
        for name in set(turtles) - set(rotators):
            rotators[name] = Rotator(name)
        for name in set(rotators) - set(turtles):
            rotators.pop(name).close(f"{name} is gone (killed)")
        now = time.monotonic()
        for name, rotator in rotators.items():
            rotator.step(latest.get(name), now)
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break
