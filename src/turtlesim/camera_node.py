"""The demo camera node (`rosrun turtlesim turtle_camera`): watches every /<turtle>/pose and publishes an overhead
picture of the world at 10 Hz as sensor_msgs/Image (rgb8, ~image_raw) and as JPEG sensor_msgs/CompressedImage
(~image_raw/compressed): a camera to try the console's camera panel with, on a machine without one."""
import io

import rospy
from sensor_msgs.msg import CompressedImage, Image

from turtlesim.camera import render
from turtlesim.msg import Pose

RATE_HZ = 10
DISCOVERY_S = 2.0


def main():
    rospy.init_node("turtle_camera")
    raw = rospy.Publisher("~image_raw", Image, queue_size=1)
    compressed = rospy.Publisher("~image_raw/compressed", CompressedImage, queue_size=1)
    poses, subscribers = {}, {}

    def watch(_event=None):
        for topic, type_name in rospy.get_published_topics():
            parts = topic.split("/")
            if type_name == "turtlesim/Pose" and len(parts) == 3 and parts[2] == "pose" and topic not in subscribers:
                name = parts[1]
                subscribers[topic] = rospy.Subscriber(
                    topic, Pose, lambda p, name=name: poses.__setitem__(name, (p.x, p.y, p.theta)), queue_size=1)

    watch()
    rospy.Timer(rospy.Duration(DISCOVERY_S), watch)
    rate = rospy.Rate(RATE_HZ)
    while not rospy.is_shutdown():
        picture = render(dict(poses))
        stamp = rospy.Time.now()
        message = Image(height=picture.height, width=picture.width, encoding="rgb8", is_bigendian=0,
                        step=3 * picture.width, data=picture.tobytes())
        message.header.stamp, message.header.frame_id = stamp, "turtle_camera"
        raw.publish(message)
        jpeg = io.BytesIO()
        picture.save(jpeg, format="JPEG", quality=80)
        small = CompressedImage(format="jpeg", data=jpeg.getvalue())
        small.header.stamp, small.header.frame_id = stamp, "turtle_camera"
        compressed.publish(small)
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break
