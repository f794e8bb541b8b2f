import os

import pytest

from harness import RosMaster


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
