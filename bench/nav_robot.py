"""The rover bench's generator (bench/nav_bench.py): a rospy node publishing what a navigation rover publishes
(nav_messages.STREAMS: a 1081-ray scan at 40 Hz, TF of 50 frames at 100 Hz, odometry, IMU, GPS fix, diagnostics,
joint states, a 300k-point cloud at 5 Hz; /tf_static and a 4000x4000 map latched), each stream from a thread of its
own on a fixed schedule, every header stamped with its publish time (wall clock). Not the bad-link bench's camera
rover (bench/rover.py).

Prints READY once the latched topics are out. Then each line on stdin is a command, answered by one
`RESULT <json>` line:
  count T0 T1   how many messages of each stream went to at least one subscriber stamped in [T0, T1) (wall time)
  map           the map again, stamped now (its subscribers get it again): {"stamp": its stamp}
  quit"""

import threading
import time

import genpy
import nav_messages
import rospy

import stats


class Stream:
    """One topic's publisher and its message, restamped for each publish; the stamps of what went out."""

    def __init__(self, stream):
        self.stream = stream
        self.msg = stream.build()
        self.headers = nav_messages.headers(self.msg)
        cls = genpy.message.get_message_class(stream.type)
        self.publisher = rospy.Publisher(stream.topic, cls, queue_size=10, latch=not stream.hz)
        self.stamps = []  # (appended by one thread, read by another: list appends are atomic)

    def publish(self):
        now = time.time()
        nav_messages.stamp(self.headers, now)
        self.publisher.publish(self.msg)
        return now

    def run(self):
        """At the stream's rate, on a fixed schedule (a late publish does not make the next ones come sooner);
        only while someone listens (rospy sends nothing to no one: a stamp then would count a message that never
        went)."""
        period = 1.0 / self.stream.hz
        due = time.monotonic()
        while not rospy.is_shutdown():
            due = max(due + period, time.monotonic() - period)
            time.sleep(max(0.0, due - time.monotonic()))
            if self.publisher.get_num_connections():
                self.stamps.append(self.publish())


def main():
    rospy.init_node("nav_robot", disable_signals=True)
    streams = {s.name: Stream(s) for s in nav_messages.STREAMS}
    for stream in streams.values():
        if stream.stream.hz:
            threading.Thread(target=stream.run, name=stream.stream.name, daemon=True).start()
        else:
            stream.publish()  # (latched: rospy keeps it for every subscriber that comes)
    print("READY", flush=True)
    stats.commands(
        {
            "count": lambda t0, t1: {
                name: stats.count_between(list(s.stamps), float(t0), float(t1))
                for name, s in streams.items()
                if s.stream.hz
            },
            "map": lambda: {"stamp": streams["map"].publish()},
        }
    )
    rospy.signal_shutdown("quit")


if __name__ == "__main__":
    main()
