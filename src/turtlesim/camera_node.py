"""The demo camera node (`rosrun turtlesim turtle_camera`): watches every /<turtle>/pose and publishes an overhead
picture of the world at 10 Hz as sensor_msgs/Image (rgb8, ~image_raw) and as JPEG sensor_msgs/CompressedImage
(~image_raw/compressed): a camera to try the console's camera panel with, on a machine without one."""

import io

import rospy
from sensor_msgs.msg import CompressedImage, Image

from turtlesim.camera import render
from turtlesim.pose_watch import PoseWatch

RATE_HZ = 10


def main():
    rospy.init_node("turtle_camera")
    raw = rospy.Publisher("~image_raw", Image, queue_size=1)
    compressed = rospy.Publisher("~image_raw/compressed", CompressedImage, queue_size=1)
    poses = PoseWatch().poses
    rate = rospy.Rate(RATE_HZ)
    while not rospy.is_shutdown():
        picture = render(dict(poses))
        stamp = rospy.Time.now()
        message = Image(
            height=picture.height,
            width=picture.width,
            encoding="rgb8",
            is_bigendian=0,
            step=3 * picture.width,
            data=picture.tobytes(),
        )
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
