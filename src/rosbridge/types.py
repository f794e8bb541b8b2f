"""ROS message and service classes by type name.

Only names of the form `package/Name` are looked up, and only through ROS's own message packages, so a
client can never make the bridge import anything else."""
import functools
import re

import genpy
import roslib.message

from rosbridge.errors import ClientError

TYPE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*/[A-Za-z][A-Za-z0-9_]*")


class UnknownType(ClientError):
    """The type name is malformed or names no message/service that ROS knows."""


def _check_name(type_name, kind):
    if not isinstance(type_name, str) or not TYPE_NAME.fullmatch(type_name):
        raise UnknownType(f"invalid {kind} type {type_name!r}: expected 'package/Name'")


@functools.lru_cache(maxsize=None)
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


@functools.lru_cache(maxsize=None)
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
