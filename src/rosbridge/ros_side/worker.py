"""The ROS work that can block, on one thread of its own: asking the master, and making or dropping rospy
publishers, subscribers and services (each a call to the master). With the master slow or stopped, only this
thread waits; the event loop goes on serving every client."""

import collections
import gc
import queue
import threading
import time

import rosgraph
import rospy

from rosbridge.errors import log_bug

IDLE_S = 2.0  # after this long without a job, the worker collects the garbage dropped objects left
GRAPH_MAX_AGE = 0.5  # seconds a snapshot of the master's topics answers for the topics it holds
GRAPH_MIN_AGE = 0.05  # a topic it lacks is asked again, but not more often than this (bursts share a look)


class RosWorker:
    def __init__(self, loop):
        self._loop = loop
        self._jobs = queue.SimpleQueue()
        self.graph = GraphSnapshot()
        self._garbage = False  # (worker only)
        self._submitted = self._finished = 0  # jobs submitted, and those whose outcome the loop has had (loop)
        self._waiters = collections.deque()  # (jobs that must be finished first, fn), in that order (loop)
        threading.Thread(target=self._run, name="ros worker", daemon=True).start()

    def submit(self, job, done=None):
        """On the loop: runs job() on the worker in order; then done(error, result) on the loop (error: the
        exception job raised, or None)."""
        self._submitted += 1
        self._jobs.put((job, done))

    def after_submitted(self, fn):
        """On the loop: if a job submitted so far is not finished, fn() runs on the loop once every one is (after
        their `done`), and True is returned; else False."""
        if self._finished == self._submitted:
            return False
        self._waiters.append((self._submitted, fn))
        return True

    def _job_finished(self, done, error, result):
        self._finished += 1
        try:
            if done is not None:
                done(error, result)
        finally:
            waiters = self._waiters
            while waiters and waiters[0][0] <= self._finished:
                try:
                    waiters.popleft()[1]()
                except Exception:  # a bug: logged; the waiters after it still go on
                    log_bug("a request held behind ROS work")

    def dropped(self):
        """On the worker, after dropping rospy objects: their sockets and epoll descriptors are freed only when
        the garbage collector gets to their reference cycles, so collect once the worker is idle (a client that
        left after 200 subscriptions must not hold 200 descriptors for minutes)."""
        self._garbage = True

    def _run(self):
        while True:
            try:
                job, done = self._jobs.get(timeout=IDLE_S)
            except queue.Empty:
                if self._garbage:
                    self._garbage = False
                    gc.collect()
                continue
            try:
                result, error = job(), None
            except Exception as exception:  # handed to `done`, which tells the client or logs the bug
                result, error = None, exception
            self._loop.add_callback(self._job_finished, done, error, result)


class GraphSnapshot:
    """The master's topics and their types. A snapshot answers for GRAPH_MAX_AGE seconds about the topics it
    holds; about others the master is asked again (a topic may have just appeared). Only the worker uses it.

    The master keeps a topic's type after its last user left, and a subscriber registering later does not
    replace it; a publisher does. So a type binds a newcomer only while someone publishes the topic
    (`published=True`), and guesses a type (for a subscribe or publish that gives none) while anyone uses it."""

    def __init__(self):
        self._master = None
        self._types = {}  # topics someone publishes or subscribes -> the master's type
        self._published = set()
        self._taken = float("-inf")

    def topic_type(self, topic, published=False):
        age = time.monotonic() - self._taken
        if age > GRAPH_MAX_AGE or (topic not in self._types and age > GRAPH_MIN_AGE):
            self.refresh()
        if published and topic not in self._published:
            return None
        return self._types.get(topic)

    def refresh(self):
        if self._master is None:  # (made here: the node has its name by now)
            self._master = rosgraph.Master(rospy.get_name())
        publishers, subscribers, _ = self._master.getSystemState()
        self._published = {name for name, _ in publishers}
        used = self._published | {name for name, _ in subscribers}
        self._types = {name: type_name for name, type_name in self._master.getTopicTypes() if name in used}
        self._taken = time.monotonic()
