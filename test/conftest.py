import os
import signal

import pytest

from harness import RosMaster

# A suite started in the background by a script (`bash .ci/run &`) inherits SIGINT and SIGQUIT ignored (POSIX shells
# do that to asynchronous commands without job control), and so would every node it starts: a test of Ctrl-C would
# find the node deaf to it. The nodes start as from a terminal instead (a handler set here is reset on exec).
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
if signal.getsignal(signal.SIGQUIT) == signal.SIG_IGN:
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)


@pytest.fixture(scope="session")
def ros(tmp_path_factory):
    """A private roscore for the whole test session. The test process itself is pointed at it too,
    so rospy can be used in-process (see the `node` fixture)."""
    master = RosMaster(tmp_path_factory.mktemp("ros")).start()
    os.environ.update({k: master.env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR")})
    yield master
    master.stop()


@pytest.fixture(scope="session")
def node(ros):
    """rospy, initialised once in the test process as an anonymous node on the private master."""
    import rospy

    rospy.init_node("pytest", anonymous=True, disable_signals=True)
    return rospy


@pytest.fixture
def laser_settings(node):
    """A dynamic_reconfigure client of the demo laser /turtle_laser (started by the test module, e.g. with rosrun);
    its settings are set back to their defaults (cfg/Laser.cfg's) after the test."""
    from dynamic_reconfigure.client import Client

    from turtlesim.cfg import LaserConfig

    client = Client("/turtle_laser", timeout=30)
    yield client
    client.update_configuration(LaserConfig.defaults)
