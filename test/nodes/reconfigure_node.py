#!/usr/bin/python3
"""A node that serves a dynamic_reconfigure configuration, for the console's Reconfigure tab.

Its configuration is dynamic_reconfigure's own test configuration, `dynamic_reconfigure.cfg.TestConfig`, which
Debian's python3-dynamic-reconfigure ships already generated (by dynamic_reconfigure's parameter generator from its
Test.cfg): ints, doubles, strings and bools, an int enum (Small, Medium, Large, ExtraLarge), ranges with and without
bounds (infinite ones too), nested groups and a collapsed one. So the test needs no build step and no hand-written
module that could drift from what the generator writes. The callback takes the configuration as the server
(clamped to the ranges) gives it, and logs it.

    test/nodes/reconfigure_node.py [__name:=tools_reconfigure]
"""

import rospy
from dynamic_reconfigure.cfg import TestConfig
from dynamic_reconfigure.server import Server


def changed(config, level):
    rospy.loginfo(
        "reconfigured (level %d): int_=%s int_enum_=%s double_=%s str_=%r bool_=%s",
        level,
        config["int_"],
        config["int_enum_"],
        config["double_"],
        config["str_"],
        config["bool_"],
    )
    return config


if __name__ == "__main__":
    rospy.init_node("tools_reconfigure")
    Server(TestConfig, changed)
    rospy.loginfo("serving dynamic_reconfigure")
    rospy.spin()
