"""Work off the event loop.

EncodingThread: work too long for the event loop: encoding a big message (a 16 MB map would hold every other
client and topic meanwhile: `bridge.encoder`), making a camera stream's JPEGs (http/camera_encoder.py), deflating a
big message for the clients whose link is slow (`bridge.deflater`, transport/connection.py and
transport/slow_link.deflated_payload: a thread apart, so that a map's encoding never holds a slow client's next
frame). One thread per use, jobs in the
order given; a thread starts with its first job.

Hand-off: run(fn, then) is called on the loop; fn() runs on the thread and must touch nothing but what it was
given (a TopicMessage's class and bytes, a frame's bytes, which nothing changes); then(result) runs on the loop
(IOLoop.add_callback), with None if fn raised (a bug, logged).

CallThreads: threads for calls that block for as long as someone else takes (a ROS service: ros_side/services.py),
so each call needs a thread of its own while it runs. A thread that finished waits a while for the next call,
and new threads are started by a thread kept for that alone, never by the caller: Thread.start() waits until the
OS has run the new thread, which on a busy machine held the loop, and every client, 0.1-0.7 s at a time
(test_isolation's victim beside a flood, calling /rosapi/get_time). Hand-off: run(fn) may be called from any
thread and never waits; fn runs on a pool thread and hands its own result back. A thread the OS refuses (a
process at its limit of tasks or memory) is asked for again every START_RETRY_S, the call waiting meanwhile: the
starter thread goes on, so the calls after it are not lost with it."""

import collections
import concurrent.futures
import itertools
import logging
import queue
import threading
import time

from rosbridge.errors import log_bug

START_RETRY_S = 0.5


class EncodingThread:
    def __init__(self, loop, name="rosbridge-encode"):
        self._loop, self._name = loop, name
        self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix=name)

    def run(self, fn, then):
        self._pool.submit(fn).add_done_callback(lambda done: self._loop.add_callback(self._finish, done, then))

    def _finish(self, done, then):
        try:
            result = done.result()
        except Exception:
            log_bug(f"a job of the {self._name} thread")
            result = None
        then(result)


class CallThreads:
    """As many threads as calls run at once; one idle for `idle_s` ends (nothing is kept for a burst gone by).
    The starter thread is started here, when the bridge starts (its own start may wait)."""

    def __init__(self, name, idle_s=60.0):
        self._name, self._idle_s = name, idle_s
        self._lock = threading.Condition(threading.Lock())
        self._jobs = collections.deque()  # under _lock, with:
        self._idle = 0  # threads waiting for a job
        self._to_start = queue.SimpleQueue()  # a None for each thread to start
        threading.Thread(target=self._start_threads, name=f"{name} starter", daemon=True).start()

    def run(self, fn):
        with self._lock:
            self._jobs.append(fn)
            if self._idle >= len(self._jobs):
                self._lock.notify()
                return
        self._to_start.put(None)

    def _start_threads(self):
        while True:
            self._to_start.get()
            self._start_one()

    def _start_one(self):
        for attempt in itertools.count():
            try:
                threading.Thread(target=self._work, name=self._name, daemon=True).start()
                return
            except RuntimeError as error:  # ("can't start new thread")
                if attempt == 0:
                    logging.getLogger("rosbridge").warning(
                        "cannot start a %s thread (%s): its call waits, asked again every %s s",
                        self._name,
                        error,
                        START_RETRY_S,
                    )
                time.sleep(START_RETRY_S)

    def _work(self):
        lock = self._lock
        with lock:
            while True:
                while not self._jobs:
                    self._idle += 1
                    woken = lock.wait(self._idle_s)
                    self._idle -= 1
                    if not woken and not self._jobs:
                        return
                job = self._jobs.popleft()
                lock.release()
                try:
                    job()
                except Exception:  # (the caller's job hands back its own errors: this is a bug)
                    log_bug(f"a job of the {self._name} threads")
                finally:
                    lock.acquire()
