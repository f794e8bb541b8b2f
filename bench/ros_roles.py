"""Plain rospy processes for the benchmarks (each role is one ROS node in its own process).

  pub   publishes `count` messages (at `rate` Hz, or as fast as rospy can when rate is 0)
  count subscribes and counts what arrives
  echo  republishes every message of one topic on another (the far end of a round trip)
  rtt   plain rospy round trips through `echo`: the baseline for the bridge's latency

Protocol with bench/suite.py: a role prints READY when it is connected, waits for a line on stdin when it is
an actor that must start on cue, and prints one `RESULT <json>` line at the end."""

import argparse
import sys
import threading
import time

import rospy

import payloads
import stats


def main():
    p = argparse.ArgumentParser()
    p.add_argument("role", choices=["pub", "count", "echo", "rtt"])
    p.add_argument("--topic", default="/bench/data")
    p.add_argument("--out", default="/bench/pong", help="echo/rtt: the topic echoed back on")
    p.add_argument("--kind", default="twist", choices=sorted(payloads.TYPES))
    p.add_argument("--count", type=int, default=1000)
    p.add_argument("--rate", type=float, default=0.0, help="Hz; 0 = as fast as possible")
    p.add_argument(
        "--queue-size",
        type=int,
        default=100,
        help="pub: rospy's queue_size (100: what roslibjs asks the bridge for); 0 = synchronous publisher",
    )
    p.add_argument("--subscribers", type=int, default=1, help="pub: connections to wait for before READY")
    p.add_argument(
        "--warmup",
        action="store_true",
        help="pub: publish seq -1 at --rate until told to go (lets websocket clients see the topic live)",
    )
    p.add_argument(
        "--stamp",
        action="store_true",
        help="pub: a Twist carries its send time in angular.y (its age at a client: payloads.stamp_of)",
    )
    p.add_argument("--idle", type=float, default=2.0, help="count: stop this long after the last message")
    p.add_argument("--timeout", type=float, default=60.0)
    a = p.parse_args()
    rospy.init_node(f"bench_{a.role}", anonymous=True, disable_signals=True)
    {"pub": pub, "count": count, "echo": echo, "rtt": rtt}[a.role](a)


def msg_class(kind):
    return type(payloads.ros_msg(kind))


def pub(a):
    # queued (rospy's writer thread sleeps after each message) or synchronous (publish() writes to the socket)
    publisher = rospy.Publisher(a.topic, msg_class(a.kind), queue_size=a.queue_size or None)
    go = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.readline(), go.set()), daemon=True).start()
    period = 1.0 / a.rate if a.rate else 0.0
    if a.warmup:
        print("READY", flush=True)
        warm = payloads.ros_msg(a.kind, -1)
        while not go.wait(period or 0.1):
            publisher.publish(warm)
    else:
        stats.wait_until(lambda: publisher.get_num_connections() >= a.subscribers, a.timeout, "subscribers")
        print("READY", flush=True)
        go.wait()
    msgs = (
        [payloads.ros_msg(a.kind, i) for i in range(min(a.count, 1000))]
        if a.kind in ("twist", "float")
        else [payloads.ros_msg(a.kind, 0)]
    )
    start = time.monotonic()
    for i in range(a.count):
        msg = msgs[i % len(msgs)]
        if a.kind == "image":
            msg.header.seq = i
        if a.kind in ("image", "cloud"):
            msg.header.stamp = rospy.Time.now()  # (its age at a client: payloads.stamp_of)
        elif a.stamp and a.kind == "twist":
            msg.angular.y = time.time()
        publisher.publish(msg)
        if period:
            time.sleep(max(0.0, start + (i + 1) * period - time.monotonic()))
    elapsed = time.monotonic() - start
    time.sleep(1.0)  # let rospy's writer thread drain its queue before the process ends
    stats.result(sent=a.count, seconds=elapsed)


def count(a):
    seen = stats.Arrivals()
    sub = rospy.Subscriber(
        a.topic,
        msg_class(a.kind),
        lambda m: seen.add(payloads.seq_of(a.kind, m)),
        queue_size=a.count,
        buff_size=1 << 24,
    )
    stats.wait_until(lambda: sub.get_num_connections() >= 1, a.timeout, "a publisher")
    print("READY", flush=True)
    seen.wait(a.count, a.idle, a.timeout)
    stats.result(**seen.summary())


def echo(a):
    cls = msg_class(a.kind)
    out = rospy.Publisher(a.out, cls, queue_size=100)
    rospy.Subscriber(a.topic, cls, out.publish, tcp_nodelay=True)
    print("READY", flush=True)
    rospy.spin()


def rtt(a):
    cls = msg_class(a.kind)
    sent = {}
    rtts = []
    back = threading.Event()

    def on_pong(m):
        seq = payloads.seq_of(a.kind, m)
        if seq < 0:
            back.set()
        elif seq in sent:
            rtts.append(time.monotonic() - sent.pop(seq))

    rospy.Subscriber(a.out, cls, on_pong, tcp_nodelay=True)
    ping = rospy.Publisher(a.topic, cls, queue_size=100, tcp_nodelay=True)
    stats.wait_until(lambda: _ping_until_echoed(ping, a.kind, back), a.timeout, "the echo node")
    print("READY", flush=True)
    period = 1.0 / (a.rate or 100.0)
    start = time.monotonic()
    for i in range(a.count):
        sent[i] = time.monotonic()
        ping.publish(payloads.ros_msg(a.kind, i))
        time.sleep(max(0.0, start + (i + 1) * period - time.monotonic()))
    stats.wait_until(lambda: not sent, 3.0, "the last echoes", fail=False)
    stats.result(**stats.latency_summary(rtts, a.count))


def _ping_until_echoed(ping, kind, back):
    ping.publish(payloads.ros_msg(kind, -1))
    return back.wait(0.2)


if __name__ == "__main__":
    main()
