"""The demo laser node (`rosrun turtlesim turtle_laser`): for every turtle, a sensor_msgs/LaserScan on
/<turtle>/scan at ~rate Hz (10) of the walls and the other turtles, computed from the poses (laser.py), in the
frame <turtle>/laser that turtle_tf places: something for the console's LaserScan viewer with turtlesim alone."""
import math

import rospy
from sensor_msgs.msg import LaserScan

from turtlesim.laser import scan
from turtlesim.pose_watch import PoseWatch


def main():
    rospy.init_node("turtle_laser")
    rate_hz, rays = rospy.get_param("~rate", 10.0), rospy.get_param("~rays", 360)
    range_max = rospy.get_param("~range_max", 12.0)
    poses, publishers = PoseWatch().poses, {}
    rate = rospy.Rate(rate_hz)
    while not rospy.is_shutdown():
        now, current = rospy.Time.now(), dict(poses)
        for name, pose in current.items():
            if name not in publishers:
                publishers[name] = rospy.Publisher(f"/{name}/scan", LaserScan, queue_size=1)
            others = [(x, y) for other, (x, y, _) in current.items() if other != name]
            message = LaserScan(angle_min=-math.pi, angle_max=math.pi - 2 * math.pi / rays,
                                angle_increment=2 * math.pi / rays, scan_time=1.0 / rate_hz, range_min=0.05,
                                range_max=range_max, ranges=scan(pose, others, rays, range_max))
            message.header.stamp, message.header.frame_id = now, name + "/laser"
            publishers[name].publish(message)
        for name in set(publishers) - set(current):  # a killed turtle
            publishers.pop(name).unregister()
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break
