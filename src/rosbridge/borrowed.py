"""Every name the bridge takes from the inside of Tornado, rospy and rosbag (not their documented API), in one place,
each with why. test/unit/test_borrowed.py checks each against the installed versions (Debian 12: Tornado 6.2,
rospy 1.15; Debian 13: Tornado 6.4, rospy 1.17), so that a version that moves one fails there, by name, and
not somewhere in a client's connection.

Everything else the bridge uses of Tornado (RequestHandler.detach, IOStream.socket / read_bytes / write /
set_close_callback / close, IOLoop.add_handler / update_handler / remove_handler, TCPServer) and of rospy is their
public API."""

import rospy
import rospy.core
import rospy.impl.masterslave
import rospy.impl.paramserver
import rospy.impl.registration
import rospy.impl.tcpros
import rospy.impl.transport
import tornado.util

# Tornado: unmasking a client's websocket payload in C (tornado.speedups), 15-30x faster than any pure Python
# way for a camera image; the pure one, rfc6455.xor_mask, gives the same bytes.
_mask = tornado.util._websocket_mask


def websocket_mask(mask, data):
    return _mask(mask, bytes(data))  # (it takes read-only bytes only)


def handle_connection(server):
    """Tornado: TCPServer's set-up of one accepted connection (TLS wrapping, then handle_stream). Accepting is
    ours (accepting.py, which pauses when file descriptors run short); TCPServer.add_sockets cannot pause."""
    return server._handle_connection


# rospy's implementation package (rospy.impl): the bridge's own TCPROS links (ros_side/links.py) join rospy's
# node as a protocol handler, so that rospy still registers the topics and lists the links in getBusInfo, while
# the loop moves the messages.
Transport = rospy.impl.transport.Transport  # a link's base: what rospy lists and closes
ProtocolHandler = rospy.impl.transport.ProtocolHandler  # what the node asks to connect a topic
INBOUND, OUTBOUND = rospy.impl.transport.INBOUND, rospy.impl.transport.OUTBOUND
get_tcpros_handler = rospy.impl.tcpros.get_tcpros_handler  # rospy's own handler, for the node's other topics
get_topic_manager = rospy.impl.registration.get_topic_manager  # topics' impls: add_connection, the lists
get_service_manager = rospy.impl.registration.get_service_manager  # the node's services, to register again
get_node_uri = rospy.core.get_node_uri  # this node's XML-RPC address, to register again


def _registration_manager():
    """This node's rospy.impl.registration.RegManager: its thread connects the topics' publishers."""
    return next(
        listener
        for listener in rospy.impl.registration.get_registration_listeners().listeners
        if isinstance(listener, rospy.impl.registration.RegManager)
    )


def node_protocol_handlers():
    """The list of protocol handlers of this node's XML-RPC handler (rospy.impl.masterslave.ROSHandler), which
    it asks in order; the bridge's links go first."""
    return _registration_manager().handler.protocol_handlers


def end_registration_thread_at_shutdown():
    """rospy's shutdown wakes its registration thread (RegManager.run) before it raises its shutdown flag, so the
    thread waits once more (0.5 s, its cond.wait) and signal_shutdown, which joins it, with it: every stop of the
    bridge took 0.6 s. A shutdown hook, which runs once the flag is up, wakes it again: 0.1 s."""
    condition = _registration_manager().cond

    def wake(_reason):
        with condition:
            condition.notify_all()

    rospy.core.add_shutdown_hook(wake)


def forget_read_index(bag):
    """rosbag: a Bag open for writing keeps an index entry of every message written (226 bytes each), for
    reading while it is open; the file's own index is made of each chunk's, kept apart. The bag recorder never
    reads a bag it writes, so it clears that list after each write (a 1 GB bag of empty messages held 3.9 GB)."""
    bag._connection_indexes.clear()


ROSOUT_SETTING = "/rosout_disable_topics_generation"


def keep_rosout_setting_cached():
    """rospy: its rosout handler reads ROSOUT_SETTING from rospy's parameter cache for every log line, and the
    cache takes an unset one ({}) for "not cached": each line asked the master, on the loop for the bridge's
    lines (every client waited while the master was slow). Asked once here (rospy subscribes to it, so a later
    value reaches the cache), and kept as unset (False) when it is."""
    try:
        rospy.get_param_cached(ROSOUT_SETTING)
    except KeyError:
        rospy.impl.paramserver.get_param_server_cache().set(ROSOUT_SETTING, False)
