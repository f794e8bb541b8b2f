"""The demo laser node (`rosrun turtlesim turtle_laser`): for every turtle, a sensor_msgs/LaserScan on
/<turtle>/scan at ~rate Hz (10) of the walls and the other turtles, computed from the poses (laser.py), in the
frame <turtle>/laser that turtle_tf places: something for the console's LaserScan viewer with turtlesim alone.

Its settings (~rate, ~rays, ~range_max, ~noise) are served by dynamic_reconfigure (rqt_reconfigure, dynparam, the
console's Reconfigure tab) and apply from the next scan, which comes at once. Their description is cfg/Laser.cfg,
from which catkin generates the module turtlesim.cfg.LaserConfig at build time, as any ROS package does, with
Debian's own pieces: the macro generate_dynamic_reconfigure_options and its templates (in
libdynamic-reconfigure-config-init-mutex-dev, Debian 12 and 13) run the .cfg with python3-dynamic-reconfigure's
parameter generator. The ranges and defaults are written once, in the .cfg, and no hand-written copy of generated
code can drift from the generator; the module is installed with the package (catkin_make install). Generating it
at run time instead would need those same templates, a writable place and the generator's command-line calling
convention, for nothing gained.
The Server reads the private parameters at start (`_rays:=90` works), clamps every value to its range and keeps the
parameters in step; the callback also refuses what the clamp lets through (NaN, a fraction for `rays`)."""

import math
import random
import threading
import time

import rospy
from dynamic_reconfigure.server import Server
from sensor_msgs.msg import LaserScan

from turtlesim.cfg import LaserConfig
from turtlesim.laser import RANGE_MIN, add_noise, scan, usable_settings
from turtlesim.pose_watch import PoseWatch

SETTINGS = tuple(LaserConfig.defaults)  # rate, rays, range_max, noise


class Laser:
    def __init__(self):
        self.settings = dict(LaserConfig.defaults)
        self.reconfigured = threading.Event()  # wakes the loop: a new setting shows in the next scan, at once
        self.poses, self.publishers = PoseWatch().poses, {}
        self.gauss = random.Random().gauss
        Server(LaserConfig, self.reconfigure)  # (calls reconfigure with the starting configuration)

    def reconfigure(self, config, _level):
        """dynamic_reconfigure's callback (on its service thread): the configuration it answers is what we run."""
        settings, refused = usable_settings({name: config[name] for name in SETTINGS}, self.settings)
        for name in refused:
            rospy.logwarn(
                "%s must be a finite %s, not %r: it stays %s",
                name,
                type(settings[name]).__name__,
                config[name],
                settings[name],
            )
        config.update(settings)
        self.settings = settings
        self.reconfigured.set()
        return config

    def run(self):
        rospy.on_shutdown(self.reconfigured.set)
        deadline = time.monotonic()
        while not rospy.is_shutdown():
            settings = self.settings
            self.publish(settings)
            deadline = max(deadline + 1.0 / settings["rate"], time.monotonic())  # no burst after a stall
            if self.reconfigured.wait(deadline - time.monotonic()):
                self.reconfigured.clear()
                deadline = time.monotonic()

    def publish(self, settings):
        rays, range_max = settings["rays"], settings["range_max"]
        now, current = rospy.Time.now(), dict(self.poses)
        for name, pose in current.items():
            if name not in self.publishers:
                self.publishers[name] = rospy.Publisher(f"/{name}/scan", LaserScan, queue_size=1)
            others = [(x, y) for other, (x, y, _) in current.items() if other != name]
            ranges = add_noise(scan(pose, others, rays, range_max), settings["noise"], range_max, self.gauss)
            message = LaserScan(
                angle_min=-math.pi,
                angle_max=math.pi - 2 * math.pi / rays,
                angle_increment=2 * math.pi / rays,
                scan_time=1.0 / settings["rate"],
                range_min=RANGE_MIN,
                range_max=range_max,
                ranges=ranges,
            )
            message.header.stamp, message.header.frame_id = now, name + "/laser"
            self.publishers[name].publish(message)
        for name in set(self.publishers) - set(current):  # a killed turtle
            self.publishers.pop(name).unregister()


def main():
    rospy.init_node("turtle_laser")
    Laser().run()
