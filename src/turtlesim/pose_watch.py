"""The turtles' poses for the demo nodes (camera, TF, laser): finds every /<name>/pose topic of type
turtlesim/Pose, now and every few seconds (turtles are spawned and killed), and keeps each turtle's latest pose."""

import rospy

from turtlesim.msg import Pose

DISCOVERY_S = 2.0


class PoseWatch:
    """poses: turtle name -> (x, y, theta), the latest. on_pose(name, pose message), if given, runs on rospy's
    subscriber threads for every pose."""

    def __init__(self, on_pose=None):
        self.poses, self._subscribers, self._on_pose = {}, {}, on_pose
        self._discover()
        rospy.Timer(rospy.Duration(DISCOVERY_S), self._discover)

    def _discover(self, _event=None):
        published = {topic for topic, type_name in rospy.get_published_topics() if type_name == "turtlesim/Pose"}
        for topic in published - set(self._subscribers):
            parts = topic.split("/")
            if len(parts) == 3 and parts[2] == "pose":
                self._subscribers[topic] = rospy.Subscriber(
                    topic, Pose, self._received, callback_args=parts[1], queue_size=1
                )
        for topic in set(self._subscribers) - published:  # a killed turtle: forget it
            self._subscribers.pop(topic).unregister()
            self.poses.pop(topic.split("/")[1], None)

    def _received(self, pose, name):
        self.poses[name] = (pose.x, pose.y, pose.theta)
        if self._on_pose is not None:
            self._on_pose(name, pose)
