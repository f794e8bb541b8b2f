"""The turtlesim node: the ROS interface of spec/turtlesim.md section 4 around the simulation core.

Threads: rospy runs topic callbacks and service handlers in its own threads; the simulation ticks in one
thread with absolute deadlines every 16 ms and hands each tick's readings to a publishing thread (rospy
yields the processor after every message it queues, which would make ticks late with many turtles); the
main thread runs the window (or just waits when there is no display). Every access to the world holds
`self.lock`. ROS registration (advertising, subscribing, registering services) happens outside that lock
so that it never delays a tick. The publishing thread and the service threads that spawn and kill turtles
share the turtles' interfaces (TurtleInterfaces): a killed turtle's is withdrawn between two publishes."""

import collections
import math
import os
import signal
import threading
import time

import rosgraph.names
import rospkg
import rospy
from geometry_msgs.msg import Twist
from std_srvs.srv import Empty, EmptyResponse

from turtlesim import view
from turtlesim.msg import Color, Pose
from turtlesim.sim import DEFAULT_BACKGROUND, DT, TurtlesimError, World
from turtlesim.srv import (
    Kill,
    KillResponse,
    SetPen,
    SetPenResponse,
    Spawn,
    SpawnResponse,
    TeleportAbsolute,
    TeleportAbsoluteResponse,
    TeleportRelative,
    TeleportRelativeResponse,
)

BACKGROUND_PARAMS = ("~background_r", "~background_g", "~background_b")
SNAPSHOT_ENV = "TURTLESIM_SNAPSHOT"
CATCH_UP_LIMIT = 0.1  # seconds: when the loop is later than this, missed ticks are dropped, not made up
UNPUBLISHED_TICKS = 16  # how far publishing may fall behind the simulation before old ticks are dropped
LOGGERS = {"info": rospy.loginfo, "warn": rospy.logwarn, "error": rospy.logerr}


def log(level, text):
    LOGGERS[level](text)


def serve(response_class, action):
    """A rospy service handler that runs action(request) and maps TurtlesimError to a failed call."""

    def handle(request):
        try:
            result = action(request)
        except TurtlesimError as error:
            raise rospy.ServiceException(str(error)) from None
        return response_class() if result is None else result

    return handle


class TurtleInterface:
    """The topics and services of one turtle, named relative to the node's namespace."""

    def __init__(self, node, name):
        self.pose = rospy.Publisher(f"{name}/pose", Pose, queue_size=1)
        self.color = rospy.Publisher(f"{name}/color_sensor", Color, queue_size=1)
        self.cmd_vel = rospy.Subscriber(f"{name}/cmd_vel", Twist, node.on_cmd_vel, callback_args=name, queue_size=1)
        self.services = [
            rospy.Service(
                f"{name}/set_pen",
                SetPen,
                serve(SetPenResponse, lambda r: node.locked(node.world.set_pen, name, r.r, r.g, r.b, r.width, r.off)),
            ),
            rospy.Service(
                f"{name}/teleport_absolute",
                TeleportAbsolute,
                serve(
                    TeleportAbsoluteResponse,
                    lambda r: node.locked(node.world.teleport_absolute, name, r.x, r.y, r.theta),
                ),
            ),
            rospy.Service(
                f"{name}/teleport_relative",
                TeleportRelative,
                serve(
                    TeleportRelativeResponse,
                    lambda r: node.locked(node.world.teleport_relative, name, r.linear, r.angular),
                ),
            ),
        ]

    def publish(self, reading):
        self.pose.publish(Pose(*reading.pose))
        self.color.publish(Color(*reading.color))

    def close(self):
        self.pose.unregister()
        self.color.unregister()
        self.cmd_vel.unregister()
        for service in self.services:
            service.shutdown()


class TurtleInterfaces:
    """Each turtle's interface (make(name): a new one, advertised), by name. The publishing thread publishes
    through them while service threads add and withdraw them: one is closed only once no publish through it is
    under way, because rospy fails a publish to a topic unregistered meanwhile, and that once ended the
    publishing thread (every pose stopped, in a CI run that killed a turtle)."""

    def __init__(self, make):
        self._make = make
        self._table = {}
        self._publishing = threading.Lock()  # held by a publish, and while one is taken out of the table

    def publish(self, readings):
        for reading in readings:
            with self._publishing:
                interface = self._table.get(reading.name)
                if interface is not None:  # None while its topics are still being advertised
                    interface.publish(reading)

    def sync(self, names):
        """Advertises the interfaces of new turtles and withdraws those of removed ones (not under the lock:
        each is a few calls to the master)."""
        with self._publishing:
            gone = [self._table.pop(name) for name in set(self._table) - names]
        for interface in gone:
            interface.close()
        for name in names - set(self._table):
            self._table[name] = self._make(name)


class TurtlesimNode:
    def __init__(self):
        self.lock = threading.Lock()  # guards self.world
        self.stopped = threading.Event()  # set when the node is done
        self._registration = threading.Lock()  # one spawn/kill/reset (and its ROS registrations) at a time
        self._interfaces = TurtleInterfaces(lambda name: TurtleInterface(self, name))
        self._unpublished = collections.deque(maxlen=UNPUBLISHED_TICKS)  # readings of recent ticks
        self._tick_done = threading.Condition()
        for param, default in zip(BACKGROUND_PARAMS, DEFAULT_BACKGROUND):
            if not rospy.has_param(param):
                rospy.set_param(param, default)
        rospy.loginfo("Starting turtlesim with node name %s", rospy.get_name())
        self.world = World(log, self._background())
        self.world.spawn_first_turtle()
        self._sync_interfaces()
        rospy.Service("clear", Empty, serve(EmptyResponse, self._clear))
        rospy.Service("reset", Empty, serve(EmptyResponse, self._reset))
        rospy.Service("spawn", Spawn, serve(SpawnResponse, self._spawn))
        rospy.Service("kill", Kill, serve(KillResponse, self._kill))

    def locked(self, action, *args):
        with self.lock:
            return action(*args)

    # ---- topics and services -------------------------------------------------------------------------

    def on_cmd_vel(self, twist, name):
        try:
            self.locked(self.world.command, name, twist.linear.x, twist.linear.y, twist.angular.z)
        except TurtlesimError as error:  # (a topic cannot answer: say it in the log, but not at 62.5 Hz)
            rospy.logwarn_throttle(5.0, f"Ignored a {name}/cmd_vel message: {error}")

    def _clear(self, _request):
        rospy.loginfo("Clearing turtlesim.")
        self.locked(self.world.clear, self._background())

    def _reset(self, _request):
        rospy.loginfo("Resetting turtlesim.")
        with self._registration:
            self.locked(self.world.reset, self._background())
            self._sync_interfaces()

    def _spawn(self, request):
        if not rosgraph.names.is_legal_name(request.name):
            raise TurtlesimError(f"Cannot spawn a turtle named [{request.name}]: not a legal ROS name")
        with self._registration:
            name = self.locked(self.world.spawn, request.x, request.y, request.theta, request.name)
            self._sync_interfaces()
        return SpawnResponse(name)

    def _kill(self, request):
        with self._registration:
            self.locked(self.world.kill, request.name)
            self._sync_interfaces()

    def _sync_interfaces(self):
        self._interfaces.sync(set(self.locked(self.world.names)))

    def _background(self):
        return tuple(self._color_param(param, default) for param, default in zip(BACKGROUND_PARAMS, DEFAULT_BACKGROUND))

    @staticmethod
    def _color_param(param, default):
        value = rospy.get_param(param, default)
        if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 255:
            return value
        rospy.logwarn(
            "Parameter %s must be an integer from 0 to 255, not %r: using %d", rospy.resolve_name(param), value, default
        )
        return default

    # ---- the simulation loop -------------------------------------------------------------------------

    def run_simulation(self):
        """Ticks every DT seconds against absolute deadlines, so the long-run rate is exactly 1/DT: a tick
        that comes late (the machine is busy) is made up at once; when far behind (more than
        CATCH_UP_LIMIT), the missed ticks are skipped, as the reference's timer does."""
        try:
            deadline = time.monotonic()
            while not rospy.is_shutdown():
                self._tick(time.monotonic())
                deadline += DT
                now = time.monotonic()
                if now - deadline > CATCH_UP_LIMIT:
                    deadline += math.floor((now - deadline) / DT) * DT
                time.sleep(max(0.0, deadline - now))
        finally:
            self.stopped.set()

    def _tick(self, now):
        with self.lock:
            readings = self.world.tick(now)
        with self._tick_done:
            self._unpublished.append(readings)
            self._tick_done.notify()

    def run_publishing(self):
        """Publishes every tick's pose and color_sensor messages, in order."""
        while not rospy.is_shutdown():
            with self._tick_done:
                if not self._tick_done.wait_for(lambda: self._unpublished, timeout=0.5):
                    continue
                readings = self._unpublished.popleft()
            self._interfaces.publish(readings)

    # ---- pictures ------------------------------------------------------------------------------------

    def snapshot(self, unless_version=None):
        """(version, trail copy, turtle views) for the view, or None if unchanged since unless_version."""
        with self.lock:
            if self.world.version == unless_version:
                return None
            return self.world.version, self.world.trail.copy(), self.world.views()

    def save_snapshot(self, *_signal):
        path = os.environ.get(SNAPSHOT_ENV) or os.path.join(rospkg.get_ros_home(), "turtlesim.png")
        _, trail, turtles = self.snapshot()
        try:
            view.compose(trail, turtles).save(path, "PNG")
            rospy.loginfo("Saved a picture of the window to %s", path)
        except OSError as error:
            rospy.logerr("Cannot save a picture of the window to %s: %s", path, error)


def main():
    # Like the reference: Ctrl-C kills the process at once (no unregistration, no clean-up).
    rospy.init_node("turtlesim", disable_signals=True)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    node = TurtlesimNode()
    signal.signal(signal.SIGUSR1, node.save_snapshot)
    threading.Thread(target=node.run_simulation, name="simulation", daemon=True).start()
    threading.Thread(target=node.run_publishing, name="publishing", daemon=True).start()
    window = view.open_window()
    if window is not None:
        window.run(node.snapshot, node.stopped, on_close=lambda: rospy.signal_shutdown("window closed"))
    while not node.stopped.wait(0.5):  # (a timed wait lets Python run the SIGUSR1 handler)
        pass
