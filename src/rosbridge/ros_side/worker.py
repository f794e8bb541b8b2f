"""The ROS work that can block, on one thread of its own: asking the master, and making or dropping rospy
publishers, subscribers and services (each a call to the master). With the master slow or stopped, only this
thread waits; the event loop goes on serving every client."""
import queue
import threading
import time

import rosgraph
import rospy

GRAPH_MAX_AGE = 0.5  # seconds a snapshot of the master's topics answers for the topics it holds
GRAPH_MIN_AGE = 0.05  # a topic it lacks is asked again, but not more often than this (bursts share a look)


class RosWorker:
    def __init__(self, loop):
        self._loop = loop
        self._jobs = queue.SimpleQueue()
        self.graph = GraphSnapshot()
        threading.Thread(target=self._run, name="ros worker", daemon=True).start()

    def submit(self, job, done=None):
        """Runs job() on the worker in order; then done(error, result) on the loop (error: the exception job
        raised, or None)."""
        self._jobs.put((job, done))

    def _run(self):
        while True:
            job, done = self._jobs.get()
            try:
                result, error = job(), None
            except Exception as exception:  # handed to `done`, which tells the client or logs the bug
                result, error = None, exception
            if done is not None:
                self._loop.add_callback(done, error, result)


class GraphSnapshot:
    """The master's topics and their types. A snapshot answers for GRAPH_MAX_AGE seconds about the topics it
    holds; about others the master is asked again (a topic may have just appeared). Only the worker uses it."""

    def __init__(self):
        self._master = None
        self._types = {}
        self._taken = float("-inf")

    def topic_type(self, topic):
        """The topic's type while someone publishes or subscribes to it, or None: the master remembers the type
        of a topic nobody uses any more, which must not bind the next user."""
        age = time.monotonic() - self._taken
        if age > GRAPH_MAX_AGE or (topic not in self._types and age > GRAPH_MIN_AGE):
            self.refresh()
        return self._types.get(topic)

    def refresh(self):
        if self._master is None:  # (made here: the node has its name by now)
            self._master = rosgraph.Master(rospy.get_name())
        publishers, subscribers, _ = self._master.getSystemState()
        used = {name for name, _ in publishers} | {name for name, _ in subscribers}
        self._types = {name: type_name for name, type_name in self._master.getTopicTypes() if name in used}
        self._taken = time.monotonic()
