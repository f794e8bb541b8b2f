#!/usr/bin/python3
"""A Fibonacci-like action server, for the console's Actions tab.

actionlib_tutorials (and its Fibonacci action) is not in Debian, and a new action type would need a catkin package
built for the tests. Debian's python3-actionlib ships actionlib's own test action, `actionlib/TestAction`
(goal `int32 goal`, feedback `int32 feedback`, result `int32 result`), generated like any other: the server takes
`goal` as the order n, sends F(1) ... F(n) as feedback, one every ~step seconds, and F(n) as the result. A cancel
(or a newer goal) preempts it with the last number reached; a negative order is aborted.

    test/nodes/fibonacci_server.py [_step:=0.1]   (action server /tools_fibonacci)
"""

import actionlib
import rospy
from actionlib.msg import TestAction, TestFeedback, TestResult


def main():
    rospy.init_node("tools_fibonacci")
    step = rospy.get_param("~step", 0.1)

    def execute(goal):
        order = goal.goal
        if order < 0:
            server.set_aborted(TestResult(result=0), f"the order must be 0 or more, not {order}")
            return
        previous, current = 0, 0 if order == 0 else 1
        for i in range(1, order + 1):
            if i > 1:
                previous, current = current, previous + current
            if server.is_preempt_requested() or rospy.is_shutdown():
                server.set_preempted(TestResult(result=previous), f"cancelled at F({i - 1})")
                return
            server.publish_feedback(TestFeedback(feedback=current))
            rospy.sleep(step)
        server.set_succeeded(TestResult(result=current), f"F({order}) = {current}")

    server = actionlib.SimpleActionServer("/tools_fibonacci", TestAction, execute, auto_start=False)
    server.start()
    rospy.loginfo("serving /tools_fibonacci")
    rospy.spin()


if __name__ == "__main__":
    main()
