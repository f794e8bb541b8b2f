"""The unit tests that need the catkin build (turtlesim's generated messages and services) are marked `ros`.
Without the build (no .build/setup.bash sourced: `pytest test/unit -m "not ros"`), their files are not collected,
and the rest, the pure parts' tests, run in seconds."""

import importlib.util

import pytest

NEEDS_BUILD = (
    "test_cbor_and_wrapping.py",
    "test_json_to_ros.py",
    "test_json_values.py",
    "test_json_values_properties.py",
    "test_messages.py",
    "test_ros_to_json.py",
    "test_turtle_interfaces.py",
)
BUILT = importlib.util.find_spec("turtlesim.msg") is not None
collect_ignore = [] if BUILT else list(NEEDS_BUILD)


def pytest_collection_modifyitems(items):
    for item in items:
        if item.path.name in NEEDS_BUILD:
            item.add_marker(pytest.mark.ros)
