"""The generated messages and services are the ones of ROS turtlesim: same names, fields and md5sums,
so that nodes and tools written for ROS turtlesim talk to ours."""

import pytest

import turtlesim.msg
import turtlesim.srv

# md5sums of ROS turtlesim (noetic); they hash the definitions, so they pin every field name and type.
MD5 = {
    (turtlesim.msg, "Color"): "353891e354491c51aabe32df673fb446",
    (turtlesim.msg, "Pose"): "863b248d5016ca62ea2e895ae5265cf9",
    (turtlesim.srv, "Spawn"): "0b2d2e872a8e2887d5ed626f2bf2c561",
    (turtlesim.srv, "Kill"): "c1f3d28f1b044c871e6eff2e9fc3c667",
    (turtlesim.srv, "SetPen"): "9f452acce566bf0c0954594f69a8e41b",
    (turtlesim.srv, "TeleportAbsolute"): "a130bc60ee6513855dc62ea83fcc5b20",
    (turtlesim.srv, "TeleportRelative"): "9d5c2dcd348ac8f76ce2a4307bd63a13",
}


@pytest.mark.parametrize("module,name", MD5.keys(), ids=[n for _, n in MD5])
def test_md5sum_matches_ros_turtlesim(module, name):
    assert getattr(module, name)._md5sum == MD5[(module, name)]
    assert getattr(module, name)._type == f"turtlesim/{name}"


def test_pose_fields():
    assert turtlesim.msg.Pose.__slots__ == ["x", "y", "theta", "linear_velocity", "angular_velocity"]
    assert turtlesim.msg.Pose._slot_types == ["float32"] * 5


def test_spawn_fields():
    assert turtlesim.srv.SpawnRequest.__slots__ == ["x", "y", "theta", "name"]
    assert turtlesim.srv.SpawnResponse.__slots__ == ["name"]
