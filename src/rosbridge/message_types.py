"""ROS message and service classes by type name.

Only names of the form `package/Name` are looked up, and only through ROS's own message packages, so a
client can never make the bridge import anything else."""

import functools
import importlib.util
import os
import re
import sys

import genpy
import roslib.message
import rospkg

from rosbridge.errors import ClientError

TYPE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*/[A-Za-z][A-Za-z0-9_]*")


class UnknownType(ClientError):
    """The type name is malformed or names no message/service that ROS knows."""


def _check_name(type_name, kind):
    if not isinstance(type_name, str) or not TYPE_NAME.fullmatch(type_name):
        raise UnknownType(f"invalid {kind} type {type_name!r}: expected 'package/Name'")
    if not _is_message_package(type_name.partition("/")[0]):
        raise UnknownType(f"unknown {kind} type {type_name!r}")


@functools.lru_cache(maxsize=1024)
def _is_message_package(package):
    """Whether `package` is a ROS package (rospack knows it) or a Python package with generated msg or srv
    modules, found without importing it: roslib imports the package to look a type up, and a client must not
    make the bridge import any other module (`this/Foo` would print the Zen of Python, `antigravity/Foo` open
    a web browser)."""
    module = sys.modules.get(package)
    if module is not None:
        locations = getattr(module, "__path__", ())  # (as extended by the package itself: catkin's halves)
    else:
        try:
            spec = importlib.util.find_spec(package)
        except (ImportError, ValueError):
            return False
        locations = (spec and spec.submodule_search_locations) or ()
    if any(os.path.isdir(os.path.join(folder, kind)) for folder in locations for kind in ("msg", "srv")):
        return True
    try:
        _ros_packages.get_path(package)
        return True
    except rospkg.ResourceNotFound:
        return False


_ros_packages = rospkg.RosPack()


@functools.cache
def message_class(type_name):
    """The genpy message class for `type_name`, e.g. 'geometry_msgs/Twist'."""
    _check_name(type_name, "message")
    try:
        cls = roslib.message.get_message_class(type_name)
    except Exception:  # roslib raises a variety of errors for packages it cannot find
        cls = None
    # roslib returns whatever the package's module has under that name (`std_msgs/sys` is a module), and
    # rospy/AnyMsg is a message class standing for any type: only a class generated for this very name counts
    if not (isinstance(cls, type) and issubclass(cls, genpy.Message) and cls._type == type_name):
        raise UnknownType(f"unknown message type {type_name!r}")
    return cls


@functools.cache
def service_class(type_name):
    """The service class for `type_name` (with _request_class and _response_class), e.g. 'std_srvs/Empty'."""
    _check_name(type_name, "service")
    try:
        cls = roslib.message.get_service_class(type_name)
    except Exception:
        cls = None
    if not (isinstance(cls, type) and hasattr(cls, "_request_class") and getattr(cls, "_type", None) == type_name):
        raise UnknownType(f"unknown service type {type_name!r}")
    return cls
