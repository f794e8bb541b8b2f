"""The ROS tutorial's own control page, written by its user and opened in a browser on the bridge's machine:
from disk (file://, the browser sends Origin "null") and from another port of this machine. With the bridge's
default origin policy both must drive the turtle."""

import functools
import http.server
import math
import shutil
import threading

import pytest

from fixtures import bridge_fixture
from harness import REPO, wait_for

ROSLIB = REPO / "web" / "node_modules" / "roslib" / "build" / "roslib.min.js"

# The tutorial's page, as its user writes it; roslib comes from beside the page instead of a CDN (no network
# here), and the bridge listens on a free port instead of 9090.
TUTORIAL_PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8" />
<script type="text/javascript" src="roslib.min.js"></script>
<script type="text/javascript">
  // Connecting to ROS
  var ros = new ROSLIB.Ros({
    url : 'ws://localhost:PORT'
  });

  ros.on('connection', function() {
    document.getElementById('status').innerHTML = 'Connected';
  });
  ros.on('error', function(error) {
    document.getElementById('status').innerHTML = 'Error';
  });
  ros.on('close', function() {
    document.getElementById('status').innerHTML = 'Closed';
  });

  // Publishing a Topic
  var cmdVel = new ROSLIB.Topic({
    ros : ros,
    name : '/turtle1/cmd_vel',
    messageType : 'geometry_msgs/Twist'
  });

  function move() {
    var twist = new ROSLIB.Message({
      linear : { x : 2.0, y : 0.0, z : 0.0 },
      angular : { x : 0.0, y : 0.0, z : 1.0 }
    });
    cmdVel.publish(twist);
  }
</script>
</head>
<body>
  <h1>Turtle control panel</h1>
  <p>Connection status: <span id="status">N/A</span></p>
  <button id="move" onclick="move()">Move</button>
</body>
</html>
"""


tutorial_bridge = bridge_fixture("tutorial_bridge", needs=("sim",))


@pytest.fixture(scope="module")
def tutorial_dir(tutorial_bridge, tmp_path_factory):
    """The page and roslib.min.js in a folder of their own, the page pointing at a bridge with default settings."""
    folder = tmp_path_factory.mktemp("tutorial")
    (folder / "index.html").write_text(TUTORIAL_PAGE.replace("PORT", str(tutorial_bridge)))
    shutil.copy(ROSLIB, folder / "roslib.min.js")
    return folder


@pytest.fixture
def static_server(tutorial_dir):
    """A plain static HTTP server of the page's folder on loopback (another port than the bridge's)."""
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(tutorial_dir))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield server.server_address[1]
    server.shutdown()
    server.server_close()


def drive_with_the_page(open_browser, node, url):
    from turtlesim.msg import Pose

    start = node.wait_for_message("/turtle1/pose", Pose, timeout=20)
    driver = open_browser().driver
    driver.get(url)
    wait_for(
        lambda: driver.find_element("id", "status").text == "Connected",
        20,
        what=f"the tutorial page at {url} to connect",
    )
    driver.find_element("id", "move").click()

    def moved():
        pose = node.wait_for_message("/turtle1/pose", Pose, timeout=20)
        return math.hypot(pose.x - start.x, pose.y - start.y) > 0.5

    wait_for(moved, 20, what="the turtle to move")


def test_the_tutorial_page_opened_from_disk_drives_the_turtle(open_browser, node, tutorial_dir):
    drive_with_the_page(open_browser, node, (tutorial_dir / "index.html").as_uri())


def test_the_tutorial_page_served_from_another_port_drives_the_turtle(open_browser, node, static_server):
    drive_with_the_page(open_browser, node, f"http://localhost:{static_server}/index.html")
