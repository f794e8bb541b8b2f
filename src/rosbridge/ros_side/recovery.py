"""Registering again with a restarted master. roscpp does it by itself; rospy does not: after roscore
restarts, a rospy node's publishers, subscribers and services are unknown to the new master, so nobody connects
to them. MasterWatch notices the restart (the master's pid changes, or it answers again after a silence) and
registers everything this node has again, as rospy does once at start-up."""

import http.client
import threading
import time
import xmlrpc.client

import rosgraph
import rospy

from rosbridge.borrowed import get_node_uri, get_service_manager, get_topic_manager
from rosbridge.ros_side.master_proxy import api_proxy

POLL_PERIOD = 1.0  # seconds between looks at the master


class MasterWatch:
    """A thread of its own (it only talks to the master and to this node's own XML-RPC server; with a stopped
    master it waits out its timeout, never the loop's). after_recovery() runs on that thread once everything
    is registered again (the bridge sets its parameters again there)."""

    def __init__(self, after_recovery):
        self._after_recovery = after_recovery
        self._master_uri = rosgraph.get_master_uri()
        # (one proxy for every look: its connection to the master is kept alive between them, which costs the idle
        # bridge about 0.38 ms of CPU a look instead of 0.63 with a new one each time; it reconnects by itself)
        self._master = api_proxy(self._master_uri)
        threading.Thread(target=self._run, name="master watch", daemon=True).start()

    def _run(self):
        known_pid = self._pid()
        while not rospy.is_shutdown():
            time.sleep(POLL_PERIOD)
            pid = self._pid()
            if pid is None or pid == known_pid:
                continue
            try:
                register_again(self._master_uri)
                self._after_recovery()
            except (OSError, http.client.HTTPException, xmlrpc.client.Error) as error:
                rospy.logwarn(
                    "the master at %s is back but registering again failed (%s); trying again", self._master_uri, error
                )
                continue
            rospy.loginfo(
                "the master at %s restarted: publishers, subscribers and services registered again", self._master_uri
            )
            known_pid = pid

    def _pid(self):
        """The master's pid, or None while it does not answer."""
        try:
            code, _, pid = self._master.getPid(rospy.get_name())
            return pid if code == 1 else None
        except (OSError, http.client.HTTPException, xmlrpc.client.Error):
            return None


def register_again(master_uri):
    """Registers this node's publications, subscriptions and services with the master, and tells its
    subscriptions who publishes now (the master's answer), as a master's publisherUpdate would."""
    master, me = api_proxy(master_uri), rospy.get_name()
    node_uri = get_node_uri()
    node = api_proxy(node_uri)  # (one connection for every subscription's update)
    topics = get_topic_manager()
    for topic, type_name in topics.get_publications():
        master.registerPublisher(me, topic, type_name, node_uri)
    for topic, type_name in topics.get_subscriptions():
        code, _, publishers = master.registerSubscriber(me, topic, type_name, node_uri)
        if code == 1:
            node.publisherUpdate("/master", topic, publishers)
    for service, service_uri in get_service_manager().get_services():
        master.registerService(me, service, service_uri, node_uri)
