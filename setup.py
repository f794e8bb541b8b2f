# Used by catkin_python_setup() only; do not call directly.
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(
    **generate_distutils_setup(
        packages=[
            "turtlesim",
            "rosbridge",
            "rosbridge.codec",
            "rosbridge.foxglove",
            "rosbridge.http",
            "rosbridge.protocol",
            "rosbridge.ros_side",
            "rosbridge.transport",
        ],
        package_dir={"": "src"},
    )
)
