"""The catkin package itself: catkin_lint is clean, and `catkin_make install` gives working nodes, launch file
and page, used from the install space alone (nothing of the devel space or the source tree on the paths)."""

import os
import shutil
import subprocess
import urllib.request

import pytest

from harness import REPO, free_port, wait_for


def test_catkin_lint_reports_nothing():
    res = subprocess.run(["catkin_lint", "--strict", "-W1", str(REPO)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr  # --strict: any warning fails


@pytest.fixture(scope="module")
def install_space(tmp_path_factory):
    """A fresh catkin workspace holding this package, built and installed."""
    ws = tmp_path_factory.mktemp("install_ws")
    pkg = ws / "src" / "turtlesim"
    pkg.mkdir(parents=True)
    for entry in REPO.iterdir():  # a copy, as a user's clone would be after setup (CMake's install of a
        if not entry.name.startswith("."):  # linked folder ignores its EXCLUDE patterns, so no links here)
            copy = shutil.copytree if entry.is_dir() else shutil.copy2
            copy(entry, pkg / entry.name)
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    res = subprocess.run(
        ["catkin_make", "-DPYTHON_EXECUTABLE=/usr/bin/python3", "install"],
        cwd=ws,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    yield ws / "install"
    shutil.rmtree(ws, ignore_errors=True)


def installed(ros, install, command):
    """Runs `command` in bash with only the install space's setup sourced, against the private master."""
    env = {
        "PATH": "/usr/bin:/bin",
        "HOME": ros.env.get("HOME", "/root"),
        "PYTHONUNBUFFERED": "1",
        **{k: ros.env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR")},
    }
    return [
        "env",
        "-i",
        *(f"{k}={v}" for k, v in env.items()),
        "bash",
        "-c",
        f"source {install}/setup.bash && exec {command}",
    ]


@pytest.mark.slow
def test_installed_messages_nodes_launch_file_and_page(ros, install_space):
    assert (install_space / "share" / "turtlesim" / "web" / "index.html").is_file()
    assert (install_space / "share" / "turtlesim" / "web" / "vendor" / "roslib.min.js").is_file()
    assert not (install_space / "share" / "turtlesim" / "web" / "node_modules").exists()
    # the demo's robot description and the mesh it names (turtle_tf reads one, Foxglove clients fetch the other)
    assert (install_space / "share" / "turtlesim" / "urdf" / "turtle.urdf").is_file()
    assert (install_space / "share" / "turtlesim" / "meshes" / "turtle_shell.stl").is_file()

    show = subprocess.run(
        installed(ros, install_space, "rosmsg show turtlesim/Pose"), capture_output=True, text=True, timeout=60
    )
    assert "float32 linear_velocity" in show.stdout, show.stdout + show.stderr
    # the demo nodes' generated types: the action's messages and the laser's dynamic_reconfigure module
    for command, expected in (
        ("rosmsg show turtlesim/RotateAbsoluteGoal", "float32 theta"),
        ("python3 -c 'from turtlesim.cfg import LaserConfig; print(LaserConfig.max)'", "'rays': 1440"),
    ):
        shown = subprocess.run(installed(ros, install_space, command), capture_output=True, text=True, timeout=60)
        assert expected in shown.stdout, shown.stdout + shown.stderr

    run_sim_and_bridge(ros, install_space, "installed")


def run_sim_and_bridge(ros, space, name):
    """`rosrun turtlesim turtlesim_node` and the bridge's launch file from `space` (its setup.bash): the turtle's
    pose is published, the bridge serves the page and roslib. Both are stopped whatever happens: a turtlesim
    left running would answer the later modules' /turtle1."""
    sim = ros.spawn(installed(ros, space, f"rosrun turtlesim turtlesim_node __name:={name}_sim"), f"{name}_sim")
    bridge = None
    try:
        sim.wait_output("Spawning turtle [turtle1]", 30)
        wait_for(
            lambda: f"/{name}_sim" in dict(ros.master().getSystemState()[0]).get("/turtle1/pose", []),
            30,
            what=f"/{name}_sim's /turtle1/pose at the master",
        )  # (registered a moment after its log line)
        port = free_port()
        bridge = ros.spawn(
            installed(
                ros,
                space,
                "roslaunch turtlesim rosbridge_websocket.launch "
                f"port:={port} address:=127.0.0.1 node_name:={name}_bridge",
            ),
            f"{name}_bridge",
        )
        assert "app.js" in wait_for(
            lambda: fetch(f"http://127.0.0.1:{port}/"), 30, what=f"the page from the {name} bridge ({bridge.log_path})"
        )
        assert "export function start" in fetch(f"http://127.0.0.1:{port}/app.js")
        assert "ROSLIB" in fetch(f"http://127.0.0.1:{port}/vendor/roslib.min.js")
    finally:
        if bridge is not None:
            bridge.stop()
        sim.stop()


# Every type a tutorial command, the page, the demo or a test reads the definition of (`rosmsg show`,
# `rossrv show`, rosapi's message details): each needs its ros-*-msgs Debian package, which tools/setup installs.
DEFINITIONS = {
    "msg": [
        "geometry_msgs/Twist",
        "geometry_msgs/Vector3",
        "std_msgs/String",
        "std_msgs/Int32",
        "rosgraph_msgs/Log",
        "turtlesim/Pose",
        "turtlesim/Color",
        "sensor_msgs/Image",
        "sensor_msgs/CompressedImage",
        "visualization_msgs/Marker",
        "turtlesim/RotateAbsoluteActionGoal",
    ],
    "srv": ["std_srvs/Empty", "std_srvs/SetBool", "std_srvs/Trigger", "turtlesim/Spawn"],
}


@pytest.mark.parametrize("kind,type_name", [(kind, name) for kind, names in DEFINITIONS.items() for name in names])
def test_definitions_are_installed(ros, kind, type_name):
    shown = ros.run([f"ros{kind}", "show", type_name], check=False)
    assert shown.returncode == 0 and shown.stdout.strip(), shown.stdout + shown.stderr


@pytest.mark.slow
def test_the_readme_workspace_route(ros, tmp_path):
    """The README's route: clone into a workspace's src, `bash tools/setup` there, `catkin_make`, then rosrun and
    roslaunch from that workspace find one executable each and the bridge serves the page."""
    pkg = tmp_path / "catkin_ws" / "src" / "turtlesim"
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    )
    for name in filter(None, listed.stdout.split("\0")):  # what a clone of this tree holds (edits included)
        if (REPO / name).is_file():
            (pkg / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / name, pkg / name)
    env = {
        "PATH": "/usr/bin:/bin",
        "HOME": os.environ.get("HOME", "/root"),
        "XDG_CACHE_HOME": str(tmp_path / "cache"),
    }  # setup's own workspace: kept out of the user's cache
    for command, cwd in (
        (["bash", "tools/setup"], pkg),
        (["catkin_make", "-DPYTHON_EXECUTABLE=/usr/bin/python3"], tmp_path / "catkin_ws"),
    ):
        res = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
        assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]

    run_sim_and_bridge(ros, tmp_path / "catkin_ws" / "devel", "workspace")


def fetch(url):
    try:
        with urllib.request.urlopen(url, timeout=5) as answer:
            return answer.read().decode()
    except OSError:
        return None
