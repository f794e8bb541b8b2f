"""Simulated time for Foxglove clients (the `time` capability), when the bridge starts with /use_sim_time set:
while a Foxglove client is connected, the ROS time (rospy follows /clock itself: the node's own /clock
subscription, which a second one in the same node would not be given) is sent to each as a binary time message
every TICK while it moves, and stamps every message it gets instead of the wall clock (the spec asks for one
time source). Pure: the ROS time and the loop's timer are given."""

from rosbridge.foxglove import wire

TICK = 0.05  # s


class SimClock:
    def __init__(self, ros_now_ns, call_later, cancel_later, sessions):
        self._ros_now_ns, self._call_later, self._cancel_later = ros_now_ns, call_later, cancel_later
        self._sessions = sessions
        self._timer = None
        self._sent = None  # the time sent last

    def now_ns(self):
        return self._ros_now_ns()

    def start(self):
        if self._timer is None:
            self._tick()

    def stop(self):
        if self._timer is not None:
            self._cancel_later(self._timer)
            self._timer, self._sent = None, None

    def _tick(self):
        now = self._ros_now_ns()
        if now != self._sent and now:  # (0: no /clock yet)
            self._sent = now
            frame = wire.time_frame(now)
            for session in list(self._sessions):
                session.send_time(frame)
        self._timer = self._call_later(TICK, self._tick)
