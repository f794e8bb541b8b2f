"""Work too long for the event loop: encoding a big message (a 16 MB map takes a second or more as JSON, which
would hold every other client and topic meanwhile). One thread for the whole bridge, jobs in the order given.

Hand-off: run(fn, then) is called on the loop; fn() runs on the encoding thread and must touch nothing but what
it was given (a TopicMessage's class and bytes, which nothing changes); then(result) runs on the loop
(IOLoop.add_callback), with None if fn raised (a bug, logged)."""
import concurrent.futures

from rosbridge.errors import log_bug


class EncodingThread:
    def __init__(self, loop):
        self._loop = loop
        self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="rosbridge-encode")

    def run(self, fn, then):
        self._pool.submit(fn).add_done_callback(lambda done: self._loop.add_callback(self._finish, done, then))

    @staticmethod
    def _finish(done, then):
        try:
            result = done.result()
        except Exception:
            log_bug("encoding a big message off the loop")
            result = None
        then(result)
