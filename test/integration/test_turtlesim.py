"""turtlesim_node as a real process, driven with the stock CLI tools and rospy like the ROS tutorials."""

import signal

import pytest

from harness import wait_for

TURTLE1_TOPICS = {"/turtle1/cmd_vel", "/turtle1/color_sensor", "/turtle1/pose"}
TURTLE1_SERVICES = {"/turtle1/set_pen", "/turtle1/teleport_absolute", "/turtle1/teleport_relative"}
GLOBAL_SERVICES = {"/clear", "/reset", "/spawn", "/kill", "/turtlesim/get_loggers", "/turtlesim/set_logger_level"}


def pose_of(rospy, name="turtle1"):
    from turtlesim.msg import Pose

    return rospy.wait_for_message(f"/{name}/pose", Pose, timeout=10)


def lines(text):
    return set(text.split())


def topics(ros):
    return lines(ros.run(["rostopic", "list"]).stdout)


def services(ros):
    return lines(ros.run(["rosservice", "list"]).stdout)


def color_of(rospy, name="turtle1"):
    from turtlesim.msg import Color

    c = rospy.wait_for_message(f"/{name}/color_sensor", Color, timeout=10)
    return c.r, c.g, c.b


def log_lines(proc):
    """The node's log messages without the '[LEVEL] [time]: ' prefix, as (level, text)."""
    result = []
    for line in proc.output().splitlines():
        if line.startswith("[") and "]: " in line:
            result.append((line[1 : line.index("]")], line.split("]: ", 1)[1]))
    return result


def test_startup_logs_and_nothing_else_headless(turtlesim):
    assert log_lines(turtlesim) == [
        ("INFO", "Starting turtlesim with node name /turtlesim"),
        ("INFO", "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], theta=[0.000000]"),
    ]


def test_the_ros_graph_of_the_node(ros, turtlesim):
    assert TURTLE1_TOPICS <= topics(ros)
    assert TURTLE1_SERVICES | GLOBAL_SERVICES <= services(ros)
    info = ros.run(["rostopic", "info", "/turtle1/pose"]).stdout
    assert "Type: turtlesim/Pose" in info and "* /turtlesim" in info
    assert "Type: turtlesim/Color" in ros.run(["rostopic", "info", "/turtle1/color_sensor"]).stdout
    assert "Type: geometry_msgs/Twist" in ros.run(["rostopic", "info", "/turtle1/cmd_vel"]).stdout
    node_info = ros.run(["rosnode", "info", "/turtlesim"]).stdout
    for name in TURTLE1_TOPICS | TURTLE1_SERVICES | GLOBAL_SERVICES:
        assert f" * {name}" in node_info
    assert "turtlesim/Spawn" in ros.run(["rosservice", "info", "/spawn"]).stdout


def test_rosmsg_show_pose(ros):
    assert ros.run(["rosmsg", "show", "turtlesim/Pose"]).stdout.split("\n")[:5] == [
        "float32 x",
        "float32 y",
        "float32 theta",
        "float32 linear_velocity",
        "float32 angular_velocity",
    ]


def test_rostopic_echo_shows_turtle1_at_rest_in_the_centre(ros, turtlesim):
    out = ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose"]).stdout
    assert out.split("\n")[:5] == [
        "x: 5.544444561004639",
        "y: 5.544444561004639",
        "theta: 0.0",
        "linear_velocity: 0.0",
        "angular_velocity: 0.0",
    ]


def test_background_parameters_default_and_the_sensor_reads_them(ros, turtlesim, node):
    assert [ros.run(["rosparam", "get", f"/turtlesim/background_{c}"]).stdout.strip() for c in "rgb"] == [
        "69",
        "86",
        "255",
    ]
    assert color_of(node) == (69, 86, 255)


def test_a_preset_background_parameter_is_kept_and_used(ros, start_turtlesim, node):
    start_turtlesim(params={"background_r": 200})
    assert ros.run(["rosparam", "get", "/turtlesim/background_r"]).stdout.strip() == "200"
    assert color_of(node) == (200, 86, 255)
    ros.run(["rosparam", "set", "/turtlesim/background_g", "10"])
    assert color_of(node) == (200, 86, 255)  # parameters are only read by clear
    ros.run(["rosservice", "call", "/clear"])
    wait_for(lambda: color_of(node) == (200, 10, 255), 10, what="the new background")


def test_a_bad_background_parameter_is_reported_and_the_default_used(ros, start_turtlesim, node):
    proc = start_turtlesim(params={"background_g": "green"})
    assert color_of(node) == (69, 86, 255)
    assert (
        "WARN",
        "Parameter /turtlesim/background_g must be an integer from 0 to 255, not 'green': using 86",
    ) in log_lines(proc)


def test_driving_with_rostopic_pub_moves_the_turtle_and_it_stops(ros, turtlesim, node):
    from turtlesim.msg import Pose

    poses = []
    recorder = node.Subscriber("/turtle1/pose", Pose, poses.append)
    try:
        wait_for(lambda: poses, 10, what="poses")
        ros.run(
            [
                "rostopic",
                "pub",
                "-1",
                "/turtle1/cmd_vel",
                "geometry_msgs/Twist",
                "{linear: {x: 2.0, y: 0.0, z: 0.0}, angular: {x: 0.0, y: 0.0, z: 0.0}}",
            ]
        )
        wait_for(
            lambda: any(p.linear_velocity for p in poses) and poses[-1].linear_velocity == 0.0,
            10,
            what="the turtle to move and stop",
        )
    finally:
        recorder.unregister()
    moving = [p for p in poses if p.linear_velocity == 2.0]
    assert moving and all(p.y == 5.544444561004639 and p.theta == 0.0 for p in moving)
    assert 7.0 < poses[-1].x < 7.6  # about 2 m (the exact 2.016 m is checked by the unit tests)
    assert color_of(node) == (179, 184, 255)  # at rest on its own trail


def test_spawn_and_kill_add_and_remove_a_turtles_interface(ros, turtlesim, node):
    assert ros.run(["rosservice", "call", "/spawn", "2", "3", "0.5", ""]).stdout.strip() == 'name: "turtle2"'
    turtlesim.wait_output("Spawning turtle [turtle2] at x=[2.000000], y=[3.000000], theta=[0.500000]")
    pose = pose_of(node, "turtle2")
    assert (pose.x, pose.y, pose.theta) == (2.0, 3.0, 0.5)
    wait_for(
        lambda: {"/turtle2/pose", "/turtle2/color_sensor", "/turtle2/cmd_vel"} <= topics(ros),
        10,
        what="turtle2's topics",
    )
    assert {"/turtle2/set_pen", "/turtle2/teleport_absolute", "/turtle2/teleport_relative"} <= services(ros)

    ros.run(["rosservice", "call", "/kill", "turtle2"])
    wait_for(
        lambda: not any(t.startswith("/turtle2/") for t in topics(ros) | services(ros)),
        10,
        what="turtle2's topics and services to go",
    )
    assert ros.run(["rosservice", "call", "/spawn", "4", "4", "0", ""]).stdout.strip() == 'name: "turtle3"'


def test_teleports_like_the_reference(ros, turtlesim, node):
    ros.run(["rosservice", "call", "/turtle1/teleport_absolute", "1", "1", "0"])
    wait_for(lambda: pose_of(node).x == 1.0, 10, what="the absolute teleport")
    ros.run(["rosservice", "call", "/turtle1/teleport_relative", "2.0", "1.57"])
    pose = wait_for(lambda: (p := pose_of(node)).theta != 0.0 and p, 10, what="the relative teleport")
    assert ("%f %f %f" % (pose.x, pose.y, pose.theta)) == "1.001593 2.999999 1.570000"
    ros.run(["rosservice", "call", "/turtle1/teleport_absolute", "--", "-1", "-1", "0"])
    turtlesim.wait_output("Oh no! I hit the wall! (Clamping from [x=-1.000000, y=12.088889])")
    pose = pose_of(node)
    assert (pose.x, pose.y, pose.linear_velocity) == (0.0, 0.0, 0.0)


def test_set_pen_clear_and_reset(ros, turtlesim, node):
    ros.run(["rosservice", "call", "/turtle1/set_pen", "255", "0", "0", "5", "0"])
    ros.run(["rosservice", "call", "/turtle1/teleport_relative", "1.0", "0"])
    wait_for(lambda: color_of(node) == (255, 0, 0), 10, what="the red trail under the turtle")
    ros.run(["rosservice", "call", "/clear"])
    wait_for(lambda: color_of(node) == (69, 86, 255), 10, what="the cleared background")
    turtlesim.wait_output("Clearing turtlesim.")

    ros.run(["rosservice", "call", "/spawn", "2", "2", "0", "bob"])
    ros.run(["rosservice", "call", "/reset"])
    turtlesim.wait_output("Resetting turtlesim.")
    wait_for(lambda: not any(t.startswith("/bob/") for t in topics(ros)), 10, what="bob to go")
    pose = wait_for(lambda: (p := pose_of(node)).x == 5.544444561004639 and p, 10, what="turtle1 in the centre")
    assert (pose.y, pose.theta) == (5.544444561004639, 0.0)
    assert log_lines(turtlesim)[-1] == (
        "INFO",
        "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], theta=[0.000000]",
    )
    assert ros.run(["rosservice", "call", "/spawn", "1", "1", "0", ""]).stdout.strip() == 'name: "turtle2"'


def test_a_width_0_pen_line_ends_under_the_sensor(ros, turtlesim, node):
    ros.run(["rosservice", "call", "/turtle1/set_pen", "0", "0", "0", "0", "1"])
    ros.run(["rosservice", "call", "/turtle1/teleport_absolute", "1", "1", "0"])
    wait_for(lambda: pose_of(node).x == 1.0, 10, what="the absolute teleport")
    ros.run(["rosservice", "call", "/turtle1/set_pen", "0", "255", "0", "0", "0"])
    ros.run(["rosservice", "call", "/turtle1/teleport_relative", "2.0", "0"])
    wait_for(lambda: pose_of(node).x == 3.0, 10, what="the relative teleport")
    assert color_of(node) == (0, 255, 0)  # Qt paints the 1-pixel line's end pixel, where the sensor reads


def assert_alive_and_publishing(proc, rospy):
    assert proc.alive()
    pose_of(rospy)


def test_bad_requests_fail_clearly_and_the_node_carries_on(ros, turtlesim, node):
    res = ros.run(["rosservice", "call", "/spawn", "1", "1", "0", "turtle1"], check=False)
    assert res.returncode != 0 and "A turtled named [turtle1] already exists" in res.stderr
    res = ros.run(["rosservice", "call", "/kill", "nobody"], check=False)
    assert res.returncode != 0 and "Tried to kill turtle [nobody], which does not exist" in res.stderr
    res = ros.run(["rosservice", "call", "/spawn", "1", "1", "0", "no spaces"], check=False)
    assert res.returncode != 0 and "not a legal ROS name" in res.stderr
    res = ros.run(["rosservice", "call", "/spawn", ".nan", "1", "0", ""], check=False)
    assert res.returncode != 0 and "x must be a finite number, not nan" in res.stderr
    assert ("ERROR", "A turtled named [turtle1] already exists") in log_lines(turtlesim)
    assert ("ERROR", "Tried to kill turtle [nobody], which does not exist") in log_lines(turtlesim)
    assert_alive_and_publishing(turtlesim, node)


def test_a_killed_turtles_services_fail(ros, turtlesim, node):
    from turtlesim.srv import TeleportAbsolute

    ros.run(["rosservice", "call", "/spawn", "1", "1", "0", "doomed"])
    held = node.ServiceProxy("/doomed/teleport_absolute", TeleportAbsolute, persistent=True)
    held(2.0, 2.0, 0.0)
    ros.run(["rosservice", "call", "/kill", "doomed"])
    with pytest.raises(node.ServiceException, match=r"There is no turtle named \[doomed\]"):
        held(3.0, 3.0, 0.0)  # (over the connection opened before the kill)
    held.close()
    res = ros.run(["rosservice", "call", "/doomed/teleport_absolute", "1", "1", "0"], check=False)
    assert res.returncode != 0
    assert_alive_and_publishing(turtlesim, node)


def test_rosnode_kill_ends_the_process(ros, turtlesim):
    ros.run(["rosnode", "kill", "/turtlesim"])
    wait_for(lambda: not turtlesim.alive(), 15, what="turtlesim_node to exit")


def test_a_second_turtlesim_takes_the_name_and_the_first_exits(ros, turtlesim, start_turtlesim):
    second = start_turtlesim()
    wait_for(lambda: not turtlesim.alive(), 15, what="the first turtlesim_node to exit")
    assert second.alive()


def test_ctrl_c_kills_the_process_at_once(turtlesim):
    turtlesim.signal(signal.SIGINT)
    wait_for(lambda: not turtlesim.alive(), 10, what="turtlesim_node to die")
    assert turtlesim.popen.returncode == -signal.SIGINT


def test_sigusr1_saves_a_snapshot_headless_too(tmp_path, start_turtlesim):
    path = tmp_path / "snap.png"
    proc = start_turtlesim(env={"TURTLESIM_SNAPSHOT": str(path)})
    proc.signal(signal.SIGUSR1)
    wait_for(path.exists, 10, what="the snapshot")
    wait_for(lambda: png_size(path) == (500, 500), 10, what="a complete PNG")


def png_size(path):
    """The picture's size, or None while the file is still being written (PIL cannot read it yet)."""
    from PIL import Image

    try:
        with Image.open(path) as picture:
            return picture.size
    except OSError:  # (PIL's UnidentifiedImageError is one)
        return None
