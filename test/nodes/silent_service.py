#!/usr/bin/python3
"""A service that takes every call and never answers (until the node stops): what a stuck robot's service looks
like to the bridge.

    test/nodes/silent_service.py [__name:=...]   (service /foxglove_hostile/silent, std_srvs/Trigger)
"""

import threading

import rospy
from std_srvs.srv import Trigger


def main():
    rospy.init_node("silent_service")
    forever = threading.Event()
    rospy.Service("/foxglove_hostile/silent", Trigger, lambda request: forever.wait())
    rospy.spin()


if __name__ == "__main__":
    main()
