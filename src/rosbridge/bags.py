"""The bag recorder: record chosen topics into rosbag files in one folder, or keep a "black box" of the last
minutes in memory and save it on demand; list and delete the bags. The messages are the bridge's own
(backend.Client subscriptions: TopicMessage, serialized bytes), written raw with the rosbag API, never
deserialized. The HTTP side is bag_pages.py.

Threads: everything here runs on the loop but the writing. One writer thread (a queue bounded in bytes: beyond it,
messages are dropped and counted) opens, writes and closes bags; what it finds out (an error, a bag done) comes back
to the loop (IOLoop.add_callback). The folder's size is bounded: once its bags reach max_bytes, a recording
stops, and saying so."""
import collections
import concurrent.futures
import re
import time
from pathlib import Path

import genpy
import rosbag

from rosbridge import globs
from rosbridge.errors import ClientError

BAG_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,100}\.bag")
WRITER_QUEUE_BYTES = 64 << 20  # messages waiting for the disk; beyond, dropped (and counted)


def bag_path(folder, name):
    """The path of bag `name` in folder, or ClientError for a name that is not a plain bag file name."""
    if not BAG_NAME.fullmatch(name or ""):
        raise ClientError(f"not a bag name: {name!r} (letters, digits, _ . - and .bag at the end)")
    return Path(folder) / name


class Writer:
    """The writer thread: jobs in order (open, write, close), each a function of the open bags."""

    def __init__(self, loop):
        self._loop = loop
        self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="rosbridge-bags")
        self.waiting_bytes = 0  # touched on the loop only (the job's size is given back there)

    def submit(self, job, size=0, then=None):
        """Runs job() on the writer thread; then(error text or None) on the loop. False if the queue is full."""
        if size and self.waiting_bytes + size > WRITER_QUEUE_BYTES:
            return False
        self.waiting_bytes += size

        def done(future):
            error = None
            try:
                future.result()
            except Exception as failure:  # a full disk, a folder gone: the recording says so
                error = f"{type(failure).__name__}: {failure}"
            self._loop.add_callback(self._finished, size, then, error)
        self._pool.submit(job).add_done_callback(done)
        return True

    def _finished(self, size, then, error):
        self.waiting_bytes -= size
        if then is not None:
            then(error)


def raw(message):
    cls = message.msg_class
    return (cls._type, bytes(message.data), cls._md5sum, cls)  # (rosbag takes bytes, not a bytearray)


def stamp(message):
    return genpy.Time.from_sec(message.stamp)


class _Subscriber:
    """A backend.Client that takes the messages of some topics (the ROS side calls it on the loop)."""
    is_closed = False

    def __init__(self, backend, topics, on_message):
        self._backend, self._on_message, self.topics, self.refused = backend, on_message, [], {}
        try:
            for topic in topics:
                self._backend.subscribe(self, topic, None)  # (ClientError: refused now)
                self.topics.append(topic)
        except ClientError:
            self.close()
            raise

    def close(self):
        self.is_closed = True
        for topic in self.topics:
            self._backend.unsubscribe(self, topic)
        self._backend.release(self)

    def deliver(self, message):
        if not self.is_closed:
            self._on_message(message)

    def ros_refused(self, op, name, text):
        self.refused[name] = text

    def request_service(self, call_id, service, args):
        pass

    def status(self, level, msg, request_id=None):
        pass


class Recorder:
    """One folder of bags: at most one recording at a time, and one black box."""

    def __init__(self, backend, loop, folder, max_bytes, blackbox_seconds, blackbox_bytes, topic_globs=None):
        self._backend, self.folder, self.max_bytes = backend, Path(folder), max_bytes
        self._topic_globs = topic_globs  # topics_glob: the same topics as the websocket
        self.folder.mkdir(parents=True, exist_ok=True)
        self._writer = Writer(loop)
        self.blackbox_seconds, self.blackbox_bytes = blackbox_seconds, blackbox_bytes
        self.recording = None  # {"name", "topics", "started", "messages", "bytes", "dropped"}
        self.last = None  # the last recording's, with "error": why it stopped by itself (None: it was stopped)
        self._recording_topics = None
        self._base_bytes = 0  # the folder's other bags when the recording started
        self._bag = None  # (writer thread only)
        self._box = collections.deque()  # (stamp, message) of the black box, oldest first
        self._box_bytes = 0
        self._box_topics = None

    # ---- what is there ----------------------------------------------------------------------------------------
    def bags(self):
        """[{name, size, modified}] of the folder's bags, newest first (the one being recorded included)."""
        found = []
        for path in self.folder.glob("*.bag"):
            if BAG_NAME.fullmatch(path.name):
                info = path.stat()
                found.append({"name": path.name, "size": info.st_size, "modified": info.st_mtime})
        return sorted(found, key=lambda bag: -bag["modified"])

    def used_bytes(self):
        return sum(bag["size"] for bag in self.bags())

    def state(self):
        box = None
        if self._box_topics is not None:
            box = {"topics": self._box_topics.topics, "seconds": self.blackbox_seconds, "messages": len(self._box),
                   "bytes": self._box_bytes, "max_bytes": self.blackbox_bytes}
        return {"recording": self.recording, "last": self.last, "blackbox": box, "bags": self.bags(), "used_bytes": self.used_bytes(),
                "max_bytes": self.max_bytes}

    def path(self, name):
        path = bag_path(self.folder, name)
        if not path.is_file():
            raise ClientError(f"no bag {name}")
        return path

    def delete(self, name):
        path = self.path(name)
        if self.recording is not None and self.recording["name"] == name:
            raise ClientError(f"{name} is being recorded: stop it first")
        path.unlink()

    # ---- recording ---------------------------------------------------------------------------------------------
    def start(self, topics, name=None):
        if self.recording is not None:
            raise ClientError(f"already recording {self.recording['name']}: stop it first")
        topics = self._topic_list(topics)
        self._base_bytes = self.used_bytes()
        if self._base_bytes >= self.max_bytes:
            raise ClientError(f"the bag folder is full ({self.max_bytes} bytes): delete some bags first")
        name = name or time.strftime("%Y-%m-%d-%H-%M-%S.bag")
        path = bag_path(self.folder, name)
        if path.exists():
            raise ClientError(f"a bag named {name} exists already")
        subscriber = _Subscriber(self._backend, topics, self._record)
        self.recording = {"name": name, "topics": topics, "started": time.time(), "messages": 0, "bytes": 0,
                          "dropped": 0}
        self._recording_topics = subscriber
        self._writer.submit(lambda: self._open(path), then=self._check)

    def _open(self, path):
        self._bag = rosbag.Bag(str(path), "w")

    def _record(self, message):
        recording = self.recording
        if recording is None:
            return
        size = len(message.data)
        if self._base_bytes + recording["bytes"] + size > self.max_bytes:
            self.stop(error=f"stopped: the bag folder reached its bound ({self.max_bytes} bytes)")
            return
        entry = (message.topic, raw(message), stamp(message))
        if self._writer.submit(lambda: self._bag.write(entry[0], entry[1], entry[2], raw=True), size, self._check):
            recording["messages"] += 1
            recording["bytes"] += size
        else:
            recording["dropped"] += 1

    def _check(self, error):
        if error and self.recording is not None:
            self.stop(error=f"stopped: {error}")

    def stop(self, error=None):
        """Ends the recording (its bag is closed once what waits is written); error: why, kept in its state."""
        if self.recording is None:
            raise ClientError("not recording")
        self._recording_topics.close()
        self.last = dict(self.recording, error=error, stopped=time.time())
        self.recording, self._recording_topics = None, None
        self._writer.submit(self._close)
        return self.last

    def _close(self):
        if self._bag is not None:
            self._bag.close()
            self._bag = None

    # ---- the black box -----------------------------------------------------------------------------------------
    def keep_blackbox(self, topics):
        """Keeps the last blackbox_seconds (at most blackbox_bytes) of `topics` in memory (empty: stops)."""
        if self._box_topics is not None:
            self._box_topics.close()
            self._box_topics = None
        self._box.clear()
        self._box_bytes = 0
        if topics:
            self._box_topics = _Subscriber(self._backend, self._topic_list(topics), self._keep)

    def _keep(self, message):
        box = self._box
        box.append(message)
        self._box_bytes += len(message.data)
        horizon = message.stamp - self.blackbox_seconds
        while box and (box[0].stamp < horizon or self._box_bytes > self.blackbox_bytes):
            self._box_bytes -= len(box.popleft().data)

    def save_blackbox(self, name=None, then=None):
        """Writes what the black box holds into a new bag; then(error or None) once it is on disk."""
        if self._box_topics is None:
            raise ClientError("the black box is off: choose its topics first")
        if self.used_bytes() + self._box_bytes > self.max_bytes:
            raise ClientError(f"the bag folder would exceed its bound ({self.max_bytes} bytes): delete some bags")
        name = name or time.strftime("blackbox-%Y-%m-%d-%H-%M-%S.bag")
        path = bag_path(self.folder, name)
        if path.exists():
            raise ClientError(f"a bag named {name} exists already")
        entries = [(m.topic, raw(m), stamp(m)) for m in self._box]

        def write():
            with rosbag.Bag(str(path), "w") as bag:
                for topic, message, when in entries:
                    bag.write(topic, message, when, raw=True)
        self._writer.submit(write, then=then)
        return name

    def close(self):
        if self.recording is not None:
            self.stop()
        self.keep_blackbox([])


    def _topic_list(self, topics):
        if not isinstance(topics, list) or not topics or \
                not all(isinstance(t, str) and t.startswith("/") for t in topics):
            raise ClientError("topics: a non-empty list of topic names (starting with /)")
        for topic in topics:
            if self._topic_globs is not None and not globs.allowed(topic, self._topic_globs):
                raise ClientError(f"topic {topic!r} is not allowed by topics_glob {self._topic_globs}")
        return list(dict.fromkeys(topics))
