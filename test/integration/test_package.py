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
    res = subprocess.run(["catkin_make", "-DPYTHON_EXECUTABLE=/usr/bin/python3", "install"], cwd=ws, env=env,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    yield ws / "install"
    shutil.rmtree(ws, ignore_errors=True)


def installed(ros, install, command):
    """Runs `command` in bash with only the install space's setup sourced, against the private master."""
    env = {"PATH": "/usr/bin:/bin", "HOME": ros.env.get("HOME", "/root"), "PYTHONUNBUFFERED": "1",
           **{k: ros.env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR")}}
    return ["env", "-i", *(f"{k}={v}" for k, v in env.items()), "bash", "-c",
            f"source {install}/setup.bash && exec {command}"]


def test_installed_messages_nodes_launch_file_and_page(ros, install_space):
    assert (install_space / "share" / "turtlesim" / "web" / "index.html").is_file()
    assert (install_space / "share" / "turtlesim" / "web" / "vendor" / "roslib.min.js").is_file()
    assert not (install_space / "share" / "turtlesim" / "web" / "node_modules").exists()

    show = subprocess.run(installed(ros, install_space, "rosmsg show turtlesim/Pose"), capture_output=True,
                          text=True, timeout=60)
    assert "float32 linear_velocity" in show.stdout, show.stdout + show.stderr

    sim = ros.spawn(installed(ros, install_space, "rosrun turtlesim turtlesim_node __name:=installed_sim"),
                    "installed_sim")
    sim.wait_output("Spawning turtle [turtle1]", 30)
    publishers = dict((topic, nodes) for topic, nodes in ros.master().getSystemState()[0])
    assert "/installed_sim" in publishers["/turtle1/pose"]

    port = free_port()
    bridge = ros.spawn(installed(ros, install_space, "roslaunch turtlesim rosbridge_websocket.launch "
                                 f"port:={port} address:=127.0.0.1 node_name:=installed_bridge"), "installed_bridge")

    def page():
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as answer:
                return answer.read().decode()
        except OSError:
            return None
    assert "<canvas" in wait_for(page, 30, what=f"the page from the installed bridge ({bridge.log_path})")
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/vendor/roslib.min.js", timeout=5) as answer:
        assert b"ROSLIB" in answer.read()
    bridge.stop()
    sim.stop()
