"""Work too long for the event loop: encoding a big message (a 16 MB map would hold every other client and topic
meanwhile: `bridge.encoder`), making a camera stream's JPEGs (streams.py), deflating a big message for the
clients whose link is slow (`bridge.deflater`, websocket.py and frames.deflated_payload: a thread apart, so that a
map's encoding never holds a slow client's next frame). One thread per use, jobs in the order given; a thread
starts with its first job.

Hand-off: run(fn, then) is called on the loop; fn() runs on the thread and must touch nothing but what it was
given (a TopicMessage's class and bytes, a frame's bytes, which nothing changes); then(result) runs on the loop
(IOLoop.add_callback), with None if fn raised (a bug, logged)."""
import concurrent.futures

from rosbridge.errors import log_bug


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
