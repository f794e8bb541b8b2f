import sys

import pytest

from rosbridge.message_types import UnknownType, message_class, service_class


def test_known_types_load():
    assert message_class("geometry_msgs/Twist")._type == "geometry_msgs/Twist"
    assert message_class("turtlesim/Pose")._type == "turtlesim/Pose"
    assert service_class("turtlesim/Spawn")._type == "turtlesim/Spawn"
    assert service_class("std_srvs/Empty")._request_class.__name__ == "EmptyRequest"


@pytest.mark.parametrize("name", ["", "Twist", "geometry_msgs/msg/Twist", "os/system", "../x/Y", "a/b/c",
                                  "geometry_msgs/Twist; rm", 42, None, "nosuchpkg/Thing", "geometry_msgs/Nope"])
def test_bad_or_unknown_names_are_refused(name):
    with pytest.raises(UnknownType):
        message_class(name)


def test_a_message_is_not_a_service():
    with pytest.raises(UnknownType):
        service_class("geometry_msgs/Twist")


@pytest.mark.parametrize("name", ["this/Foo", "antigravity/Foo", "email/Message", "json/Thing"])
def test_a_type_name_never_imports_a_module_that_is_not_a_message_package(name):
    package = name.partition("/")[0]
    was_loaded = package in sys.modules
    with pytest.raises(UnknownType):
        message_class(name)
    with pytest.raises(UnknownType):
        service_class(name)
    assert (package in sys.modules) == was_loaded
