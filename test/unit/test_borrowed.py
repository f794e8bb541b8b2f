"""The names rosbridge.borrowed takes from inside Tornado and rospy, checked against the installed versions:
a version that moves or changes one fails here, by name (see borrowed.py for why each is used)."""

import inspect
import os

import pytest
import rospy.core
import rospy.impl.masterslave
import rospy.impl.paramserver
import rospy.impl.registration
import rospy.impl.rosout
import rospy.topics
import tornado.tcpserver

from rosbridge import borrowed
from rosbridge.transport.rfc6455 import xor_mask


def test_tornado_websocket_mask_unmasks_as_rfc_6455_says():
    key, data = os.urandom(4), os.urandom(70_000)
    assert borrowed.websocket_mask(key, memoryview(data)) == xor_mask(key, data)
    assert borrowed.websocket_mask(key, b"") == b""


def test_tornado_tcpserver_sets_up_an_accepted_connection():
    handle = borrowed.handle_connection(tornado.tcpserver.TCPServer())
    assert list(inspect.signature(handle).parameters) == ["connection", "address"]
    assert "handle_stream" in inspect.getsource(handle)  # (it ends in the public override point)


def test_rospy_transport_and_protocol_handler_keep_their_interface():
    assert list(inspect.signature(borrowed.Transport.__init__).parameters)[:3] == ["self", "direction", "name"]
    for method in ("close", "write_data", "get_transport_info"):
        assert callable(getattr(borrowed.Transport, method, None)), method
    for method in ("supports", "get_supported", "init_publisher", "create_transport", "shutdown"):
        assert callable(getattr(borrowed.ProtocolHandler, method, None)), method
    assert borrowed.INBOUND != borrowed.OUTBOUND


def test_rospy_managers_have_what_the_bridge_asks_of_them():
    topics = borrowed.get_topic_manager()
    for method in ("get_subscriber_impl", "get_publisher_impl", "get_publications", "get_subscriptions"):
        assert callable(getattr(topics, method)), method
    assert callable(borrowed.get_service_manager().get_services)
    assert callable(borrowed.get_tcpros_handler().create_transport)
    assert callable(borrowed.get_node_uri)
    for name in ("add_connection", "connections"):
        assert name in inspect.getsource(rospy.topics._TopicImpl), name


def test_rospy_node_handler_asks_its_protocol_handlers_in_order():
    assert "self.protocol_handlers" in inspect.getsource(rospy.impl.masterslave.ROSHandler.__init__)
    assert "handler" in inspect.signature(rospy.impl.registration.RegManager.__init__).parameters
    assert isinstance(rospy.impl.registration.get_registration_listeners().listeners, list)


def test_rospy_registration_thread_waits_on_a_condition_until_shutdown():
    assert "self.cond = threading.Condition()" in inspect.getsource(rospy.impl.registration.RegManager.__init__)
    run = inspect.getsource(rospy.impl.registration.RegManager.run)
    assert "cond.wait(" in run and "is_shutdown()" in run
    assert callable(rospy.core.add_shutdown_hook)


def test_rosbag_keeps_an_index_entry_per_message_written_that_can_be_cleared(tmp_path):
    import rosbag
    from std_msgs.msg import Empty

    with rosbag.Bag(str(tmp_path / "a.bag"), "w") as bag:
        for _ in range(3):
            bag.write("/empty", Empty())
        assert sum(map(len, bag._connection_indexes.values())) == 3
        borrowed.forget_read_index(bag)
        assert not bag._connection_indexes
        bag.write("/empty", Empty())
    with rosbag.Bag(str(tmp_path / "a.bag")) as bag:  # the file's own index is whole
        assert bag.get_message_count() == 4


def test_rospys_rosout_handler_reads_the_setting_that_the_bridge_keeps_cached():
    """Each log line reads it through rospy's cache, which takes an unset ({}) value for "not cached"; one set in
    the cache is read from it."""
    assert f'get_param_cached("{borrowed.ROSOUT_SETTING}"' in inspect.getsource(rospy.impl.rosout._rosout)
    cache = rospy.impl.paramserver.ParamServerCache()
    cache.set(borrowed.ROSOUT_SETTING, {})
    with pytest.raises(KeyError):
        cache.get(borrowed.ROSOUT_SETTING)
    cache.set(borrowed.ROSOUT_SETTING, False)
    assert cache.get(borrowed.ROSOUT_SETTING) is False
