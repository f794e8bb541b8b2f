"""The demo TF node (`rosrun turtlesim turtle_tf`): a transform world -> <turtle> on /tf for every pose a turtle
publishes, and on /tf_static (latched) where the demo camera and each turtle's laser sit: something for the
console's TF viewer to show with turtlesim alone. It also sets /robot_description to urdf/turtle.urdf (turtle1 as a
model with a mesh, for 3D viewers such as Lichtblick). turtlesim_node itself stays exactly the reference's."""

import math
from pathlib import Path

import rospkg
import rospy
from geometry_msgs.msg import TransformStamped
from tf2_msgs.msg import TFMessage

from turtlesim.pose_watch import PoseWatch
from turtlesim.sim import HEIGHT, WIDTH

WORLD = "world"
CAMERA_HEIGHT = 12.0  # m above the world's centre, looking down


def transform(parent, child, x, y, z, yaw=0.0, roll=0.0, stamp=None):
    message = TransformStamped()
    message.header.stamp, message.header.frame_id, message.child_frame_id = stamp or rospy.Time.now(), parent, child
    message.transform.translation.x, message.transform.translation.y = x, y
    message.transform.translation.z = z
    cr, sr, cy, sy = math.cos(roll / 2), math.sin(roll / 2), math.cos(yaw / 2), math.sin(yaw / 2)
    rotation = message.transform.rotation
    rotation.x, rotation.y, rotation.z, rotation.w = sr * cy, sr * sy, cr * sy, cr * cy  # yaw after roll
    return message


def main():
    rospy.init_node("turtle_tf")
    package = Path(rospkg.RosPack().get_path("turtlesim"))
    rospy.set_param("/robot_description", (package / "urdf" / "turtle.urdf").read_text())
    dynamic = rospy.Publisher("/tf", TFMessage, queue_size=100)
    static = rospy.Publisher("/tf_static", TFMessage, queue_size=1, latch=True)
    static_frames = {
        "turtle_camera": transform(WORLD, "turtle_camera", WIDTH / 2, HEIGHT / 2, CAMERA_HEIGHT, roll=math.pi)
    }

    def on_pose(name, pose):
        dynamic.publish(TFMessage([transform(WORLD, name, pose.x, pose.y, 0.0, yaw=pose.theta)]))
        if name not in static_frames:  # each turtle's laser, 10 cm above its centre
            static_frames[name] = transform(name, name + "/laser", 0.0, 0.0, 0.1)
            static.publish(TFMessage(list(static_frames.values())))

    static.publish(TFMessage(list(static_frames.values())))
    PoseWatch(on_pose)
    rospy.spin()
