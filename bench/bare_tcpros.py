"""A bare TCPROS subscriber for the benchmarks' ceilings (cloud_roles.py serve, foxglove_ceiling.py): one
connection to a topic's first publisher, found through the master, with no ROS node of its own and no rospy
objects; the connection header exchanged as the bridge exchanges it (rosbridge.ros_side.tcpros), then the socket
is the caller's to read."""

import socket
import time
import xmlrpc.client

import rosgraph

from rosbridge.ros_side import tcpros


def publisher_address(topic, callerid, timeout):
    """(host, port) of the TCPROS server of topic's first publisher, once the master knows one."""
    master = rosgraph.Master(callerid)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        publishers = dict(master.getSystemState()[0]).get(topic)
        if publishers:
            code, message, protocol = xmlrpc.client.ServerProxy(master.lookupNode(publishers[0])).requestTopic(
                callerid, topic, [["TCPROS"]]
            )
            if code == 1:
                return protocol[1], protocol[2]
        time.sleep(0.1)
    raise SystemExit(f"no publisher of {topic} in {timeout} s")


def read_exactly(sock, size):
    """`size` bytes from a blocking socket, read into one buffer."""
    buffer = bytearray(size)
    view, got = memoryview(buffer), 0
    while got < size:
        count = sock.recv_into(view[got:])
        if not count:
            raise SystemExit("the publisher left")
        got += count
    return buffer


def subscribe(topic, cls, callerid, timeout):
    """A blocking socket subscribed to topic's first publisher (messages of class `cls`), its reply header read:
    the next bytes are the messages, each a 4-byte length and the message."""
    sock = socket.create_connection(publisher_address(topic, callerid, timeout))
    sock.sendall(tcpros.encode_header(tcpros.subscriber_header(topic, cls, callerid)))
    reply = tcpros.decode_header(bytes(read_exactly(sock, tcpros.header_size(read_exactly(sock, 4)))))
    if "error" in reply:
        raise SystemExit(f"the publisher refused: {reply['error']}")
    return sock
