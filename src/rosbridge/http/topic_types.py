"""The master's topic types for the camera streams and /cloud: one look-up shared by the requests that come
while it runs (the backend's /rosapi/topics, on one of its service-call threads; the reply comes on the loop)."""

import time

from rosbridge.errors import ClientError, log_bug
from rosbridge.http.no_op_client import NoOpClient

WAIT_POLL = 1.0  # seconds between looks at the master for a topic nobody publishes yet
TYPES_MAX_AGE = 0.5  # seconds the master's topic types answer for
LOOKUP_TIMEOUT = 5.0


class TopicTypes(NoOpClient):
    """The allowed topics' types, from the backend's /rosapi/topics (filtered by topics_glob), asked at most once
    per TYPES_MAX_AGE; the requests that come while a look-up runs share it. It is the look-ups' contract.Client
    (nothing else is ever sent to a look-up)."""

    def __init__(self, backend):
        self._backend = backend
        self._types, self._taken = None, float("-inf")
        self._waiting = None  # callbacks waiting for the look-up in flight

    def get(self, callback):
        """callback(types, None) or callback(None, error text), on the loop (at once when fresh)."""
        if self._types is not None and time.monotonic() - self._taken < TYPES_MAX_AGE:
            callback(self._types, None)
            return
        if self._waiting is not None:
            self._waiting.append(callback)
            return
        self._waiting = [callback]
        try:
            self._backend.call_service(self, "/rosapi/topics", {}, None, LOOKUP_TIMEOUT, self._answered)
        except ClientError as error:
            self._answered(False, str(error))

    def _answered(self, ok, values):
        waiting, self._waiting = self._waiting or [], None
        if ok:
            self._types, self._taken = dict(zip(values["topics"], values["types"])), time.monotonic()
        for callback in waiting:
            try:
                callback(self._types, None) if ok else callback(None, str(values))
            except Exception:
                log_bug("answering a camera stream's topic look-up")
