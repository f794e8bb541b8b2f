"""The bag recorder: record chosen topics into rosbag files in one folder, or keep a "black box" of the last
minutes in memory and save it on demand; list and delete the bags. The messages are the bridge's own
(contract.Client subscriptions: TopicMessage, serialized bytes), written raw with the rosbag API, never
deserialized. The HTTP side is bag_routes.py; what bags take and their bounds, bag_bounds.py.

Threads: everything here runs on the loop but the writing. One writer thread (a queue bounded in jobs and in bytes:
beyond, messages are dropped and counted) opens, writes and closes bags; what it finds out (an error, a bag done)
comes back to the loop (IOLoop.add_callback). The folder's size is bounded, counted as the disk counts it: each bag
reserves what it will take before it is written (a save all of it, before it is accepted; a recording message by
message), so bags written at once never add up past max_bytes, and a recording stops there, saying so. One black
box save is written at a time (another is refused, Busy: each would keep the box as it was, and wait). Only plain
files are bags: a symlink in the folder is neither listed, served nor deleted (it could lead out of the folder)."""

import concurrent.futures
import os
import re
import stat
import time
from pathlib import Path

import genpy
import rosbag

from rosbridge import globs
from rosbridge.borrowed import forget_read_index
from rosbridge.errors import ClientError
from rosbridge.http.bag_bounds import MESSAGE, BagSize, BlackBox, FolderSpace

BAG_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,100}\.bag")
WRITER_QUEUE_BYTES = 64 << 20  # messages waiting for the disk, as they will take it; beyond, dropped (and counted)
WRITER_QUEUE_JOBS = 20_000  # and as many at most: each job is some 500 bytes of Python objects, an empty message's too


class Busy(ClientError):
    """Refused for now: what it asks is being done for another request."""


def bag_path(folder, name):
    """The path of bag `name` in folder, or ClientError for a name that is not a plain bag file name."""
    if not isinstance(name, str) or not BAG_NAME.fullmatch(name):
        raise ClientError(f"name: not a bag name: {name!r} (letters, digits, _ . - and .bag at the end)")
    return Path(folder) / name


class Writer:
    """The writer thread: jobs in order (open, write, close), each a function of the open bags."""

    def __init__(self, loop):
        self._loop = loop
        self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="rosbridge-bags")
        self.waiting_bytes = self.waiting_jobs = 0  # touched on the loop only (a job's are given back there)

    def submit(self, job, size=0, then=None):
        """Runs job() on the writer thread; then(error text or None) on the loop. A message's job (size: its bytes
        in the bag) is refused (False) once the queue is full; the others (open, close, save) never are."""
        if size and (self.waiting_jobs >= WRITER_QUEUE_JOBS or self.waiting_bytes + size > WRITER_QUEUE_BYTES):
            return False
        self.waiting_bytes += size
        self.waiting_jobs += 1

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
        self.waiting_jobs -= 1
        if then is not None:
            then(error)


def raw(cls, data):
    return (cls._type, bytes(data), cls._md5sum, cls)  # (rosbag takes bytes, not a bytearray)


def write_message(bag, topic, message, when):
    """bag.write(raw) without the index of every message that rosbag.Bag keeps in memory (borrowed.py)."""
    bag.write(topic, message, when, raw=True)
    forget_read_index(bag)


class _Subscriber:
    """A contract.Client that takes the messages of some topics (the ROS side calls it on the loop)."""

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

    def deliver(self, read):
        for message in read.messages:
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
        self._space = FolderSpace(max_bytes)
        self.blackbox_seconds, self.blackbox_bytes = blackbox_seconds, blackbox_bytes
        self.recording = None  # {"name", "topics", "started", "messages", "bytes" (its bag's, counted), "dropped"}
        self.last = None  # the last recording's, with "error": why it stopped by itself (None: it was stopped)
        self._recording_topics = None
        self._size = None  # the recording's BagSize
        self._bag = None  # (writer thread only)
        self._box = None  # the BlackBox
        self._box_topics = None
        self._saving = None  # the bag a black box save is writing

    # ---- what is there ----------------------------------------------------------------------------------------
    def bags(self):
        """[{name, size, modified}] of the folder's bags, newest first (those being written included); counts them
        in the folder's space."""
        found = []
        for path in self.folder.glob("*.bag"):
            try:
                info = path.lstat()
            except FileNotFoundError:  # (deleted meanwhile)
                continue
            if BAG_NAME.fullmatch(path.name) and stat.S_ISREG(info.st_mode):
                found.append({"name": path.name, "size": info.st_size, "modified": info.st_mtime})
        self._space.scan({bag["name"]: bag["size"] for bag in found})
        return sorted(found, key=lambda bag: -bag["modified"])

    def state(self):
        bags = self.bags()
        box = None
        if self._box_topics is not None:
            box = {
                "topics": self._box_topics.topics,
                "seconds": self.blackbox_seconds,
                "messages": len(self._box),
                "bytes": self._box.bytes,
                "max_bytes": self.blackbox_bytes,
            }
        return {
            "recording": self.recording,
            "last": self.last,
            "blackbox": box,
            "bags": bags,
            "used_bytes": self._space.used,
            "max_bytes": self.max_bytes,
        }

    def path(self, name):
        """The path of bag `name`, a plain file of the folder, or ClientError."""
        path = bag_path(self.folder, name)
        try:
            is_bag = stat.S_ISREG(path.lstat().st_mode)
        except FileNotFoundError:
            is_bag = False
        if not is_bag:
            raise ClientError(f"no bag {name}")
        return path

    def delete(self, name):
        path = self.path(name)
        if self.recording is not None and self.recording["name"] == name:
            raise ClientError(f"{name} is being recorded: stop it first")
        if self._space.writing(name):
            raise ClientError(f"{name} is being written: delete it once it is")
        path.unlink()
        self.bags()

    def _new_name(self, name, pattern):
        """name (None or "": one made of pattern and the time), once it is a bag name that no bag has."""
        if name is None or name == "":
            stem = time.strftime(pattern)
            name, copies = f"{stem}.bag", 1
            while self._taken(name):  # (saves within the same second)
                copies += 1
                name = f"{stem}-{copies}.bag"
        elif self._taken(name):
            raise ClientError(f"a bag named {name} exists already")
        return name

    def _taken(self, name):
        return os.path.lexists(bag_path(self.folder, name)) or self._space.writing(name)

    def _written(self, name):
        """name's writing is over (done or failed): its file counts as it is on disk."""
        self._space.release(name)
        self.bags()

    # ---- recording ---------------------------------------------------------------------------------------------
    def start(self, topics, name=None):
        if self.recording is not None:
            raise ClientError(f"already recording {self.recording['name']}: stop it first")
        name = self._new_name(name, "%Y-%m-%d-%H-%M-%S")
        topics = self._topic_list(topics)
        size = BagSize()
        self.bags()
        if not self._space.reserve(name, size.total):
            raise ClientError(f"the bag folder is full ({self.max_bytes} bytes): delete some bags first")
        try:
            subscriber = _Subscriber(self._backend, topics, self._record)
        except ClientError:
            self._space.release(name)
            raise
        self.recording = {
            "name": name,
            "topics": topics,
            "started": time.time(),
            "messages": 0,
            "bytes": size.total,
            "dropped": 0,
        }
        self._size, self._recording_topics = size, subscriber
        path = self.folder / name
        self._writer.submit(lambda: self._open(path), then=self._check)

    def _open(self, path):
        self._bag = rosbag.Bag(str(path), "w")

    def _record(self, message):
        recording = self.recording
        if recording is None:
            return
        topic, cls, length = message.topic, message.msg_class, len(message.data)
        grown = self._size.after(topic, cls, length)
        if grown > self._space.room(recording["name"]):
            self.stop(error=f"stopped: the bag folder reached its bound ({self.max_bytes} bytes)")
            return
        entry = (topic, raw(cls, message.data), genpy.Time.from_sec(message.stamp))
        if self._writer.submit(lambda: write_message(self._bag, *entry), MESSAGE + length, self._check):
            self._size.add(topic, cls, length)
            self._space.reserve(recording["name"], grown)
            recording["messages"] += 1
            recording["bytes"] = grown
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
        name = self.recording["name"]
        self.last = dict(self.recording, error=error, stopped=time.time())
        self.recording, self._recording_topics, self._size = None, None, None
        self._writer.submit(self._close, then=lambda _: self._written(name))
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
        if topics:
            self._box = BlackBox(self.blackbox_seconds, self.blackbox_bytes)  # (before: a latched message comes now)
            self._box_topics = _Subscriber(self._backend, self._topic_list(topics), self._keep)
        else:
            self._box = None

    def _keep(self, message):
        self._box.add(message.stamp, message.topic, message.msg_class, message.data)

    def save_blackbox(self, name=None, then=None):
        """Writes what the black box holds into a new bag, once the folder has room for it and no other save is
        being written (Busy: each holds a copy of the box and the writer); then(error or None) once it is on
        disk."""
        name = self._new_name(name, "blackbox-%Y-%m-%d-%H-%M-%S")
        if self._box_topics is None:
            raise ClientError("the black box is off: choose its topics first")
        if self._saving is not None:
            raise Busy(f"the black box is being saved into {self._saving}: save again once it is written")
        self.bags()
        if not self._space.reserve(name, self._box.bag_bytes()):
            raise ClientError(f"the bag folder would exceed its bound ({self.max_bytes} bytes): delete some bags")
        entries, path = self._box.entries(), self.folder / name

        def write():
            with rosbag.Bag(str(path), "w") as bag:
                for when, topic, cls, data in entries:
                    write_message(bag, topic, raw(cls, data), genpy.Time.from_sec(when))

        def written(error):
            self._saving = None
            self._written(name)
            if then is not None:
                then(error)

        self._saving = name
        self._writer.submit(write, then=written)
        return name

    def close(self):
        if self.recording is not None:
            self.stop()
        self.keep_blackbox([])

    def _topic_list(self, topics):
        if (
            not isinstance(topics, list)
            or not topics
            or not all(isinstance(t, str) and t.startswith("/") for t in topics)
        ):
            raise ClientError("topics: a non-empty list of topic names (starting with /)")
        for topic in topics:
            if self._topic_globs is not None and not globs.allowed(topic, self._topic_globs):
                raise ClientError(f"topic {topic!r} is not allowed by topics_glob {self._topic_globs}")
        return list(dict.fromkeys(topics))
