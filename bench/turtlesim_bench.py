#!/usr/bin/python3
"""turtlesim_node under load: pose rate per turtle and the node's CPU use, with 1 and with 50 turtles all
driving in circles (so every tick also draws trail), headless and with a window on Xvfb.

Starts its own roscore on a free port. Prints a markdown table. Target: 62.5 Hz +-2 % per turtle.
Run from the repository with the workspace sourced:
    source .build/setup.bash && /usr/bin/python3 bench/turtlesim_bench.py [--seconds 10]"""

import argparse
import math
import os
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "testkit"))
from harness import ProcStat, RosMaster, make_workdir, wait_for  # noqa: E402  (the test harness starts the processes)
from reporting import markdown, markdown_row  # noqa: E402

TARGET_HZ = 62.5
TURN = 0.8  # rad/s: every turtle drives in circles


def measure(ros, rospy, turtles, display, seconds):
    from geometry_msgs.msg import Twist

    from turtlesim.msg import Pose
    from turtlesim.srv import Spawn

    env = {"DISPLAY": display} if display else {"DISPLAY": ""}
    node = ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], f"turtlesim-{turtles}-{bool(display)}", env=env)
    try:
        node.wait_output("Spawning turtle [turtle1]", 30)
        rospy.wait_for_service("/spawn", 30)
        spawn = rospy.ServiceProxy("/spawn", Spawn)
        names = ["turtle1"] + [spawn(1.0 + (i % 9), 1.0 + (i // 9) * 1.5, 0.0, "").name for i in range(turtles - 1)]
        counts = dict.fromkeys(names, 0)
        turned = dict.fromkeys(names, 0.0)  # radians since the start, from theta steps
        last_theta = {}
        lock = threading.Lock()

        def count(pose, name):
            with lock:
                counts[name] += 1
                if name in last_theta:
                    turned[name] += (pose.theta - last_theta[name]) % (2 * math.pi)
                last_theta[name] = pose.theta

        subscribers = [rospy.Subscriber(f"/{n}/pose", Pose, count, callback_args=n) for n in names]
        drivers = [rospy.Publisher(f"/{n}/cmd_vel", Twist, queue_size=1) for n in names]
        wait_for(lambda: all(s.get_num_connections() for s in subscribers + drivers), 30, what="connections")
        twist = Twist()
        twist.linear.x, twist.angular.z = 1.0, TURN

        def drive():
            for publisher in drivers:
                publisher.publish(twist)

        for _ in range(4):  # warm up
            drive()
            time.sleep(0.5)
        with lock:
            counts.update(dict.fromkeys(names, 0))
            turned.update(dict.fromkeys(names, 0.0))
        start, cpu_start = time.monotonic(), ProcStat(node.pid).cpu_seconds()
        while time.monotonic() - start < seconds:
            drive()
            time.sleep(0.5)
        with lock:
            final, final_turned = dict(counts), dict(turned)
        elapsed = time.monotonic() - start
        cpu = (ProcStat(node.pid).cpu_seconds() - cpu_start) / elapsed * 100
        for s in subscribers + drivers:
            s.unregister()
        rates = [final[n] / elapsed for n in names]
        # every tick turns each turtle by exactly TURN * DT, received or not
        tick_rate = min(final_turned.values()) / (TURN * 0.016) / elapsed
        return min(rates), sum(rates) / len(rates), max(rates), tick_rate, cpu
    finally:
        ros.run(["rosnode", "kill", "/turtlesim"], check=False)
        try:
            wait_for(lambda: not node.alive(), 10)
        except AssertionError:
            pass
        node.stop()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring time per case")
    parser.add_argument("--turtles", type=int, nargs="+", default=[1, 50])
    args = parser.parse_args()

    ros = RosMaster(make_workdir("turtlesim-bench-")).start()
    os.environ.update({k: ros.env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR")})
    import rospy

    rospy.init_node("turtlesim_bench", anonymous=True, disable_signals=True)
    xvfb, display = ros.start_xvfb()
    try:
        print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start\n")
        head = [
            "turtles",
            "view",
            "pose rate per turtle, Hz (min / mean / max)",
            "within 62.5 Hz +-2 %",
            "ticks simulated, Hz",
            "node CPU, % of one core",
        ]
        print(markdown(head, ["---"] * 6, []))
        for turtles in args.turtles:
            for view in (None, display):
                low, mean, high, ticks, cpu = measure(ros, rospy, turtles, view, args.seconds)
                ok = "yes" if abs(low - TARGET_HZ) <= 0.02 * TARGET_HZ and high <= TARGET_HZ * 1.02 else "NO"
                cells = [f"{turtles}", "Xvfb window" if view else "headless", f"{low:.2f} / {mean:.2f} / {high:.2f}"]
                print(markdown_row([*cells, ok, f"{ticks:.2f}", f"{cpu:.0f}"]), flush=True)
    finally:
        xvfb.stop()
        rospy.signal_shutdown("done")
        ros.stop()


if __name__ == "__main__":
    main()
