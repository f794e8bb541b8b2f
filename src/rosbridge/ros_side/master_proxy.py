"""XML-RPC to the ROS master (and a node's API) for the bridge's own looks at it: the restart watch (recovery.py)
and the Foxglove clients' graph (graph_watch.py) ask the same thing every second or half second, mostly to hear
the same answer. Each proxy keeps its connection alive between calls (rosgraph's servers speak HTTP/1.1), gives
up after MASTER_TIMEOUT, and parses an answer only when its bytes differ from the last few answers'."""

import xmlrpc.client

MASTER_TIMEOUT = 3.0  # seconds one call may take
ANSWERS_KEPT = 4  # the last answers of different bytes (a poll alternates a few calls)


class MasterError(Exception):
    """The master answered with an error code (its message is the exception's)."""


class _Transport(xmlrpc.client.Transport):
    # The master gzips answers over 1,400 bytes when asked to (the graph of a small robot is 6 kB), and Python
    # unzips them a kilobyte at a time: on the usual loopback that costs more than the bytes saved.
    accept_gzip_encoding = False

    def __init__(self):
        super().__init__()
        self._answers = {}  # body -> its answer, oldest first

    def make_connection(self, host):
        connection = super().make_connection(host)
        connection.timeout = MASTER_TIMEOUT
        return connection

    def parse_response(self, response):
        """An answer seen lately is the same object as then, not parsed again. (A look at a 6 kB graph cost 0.30 ms
        of CPU; without unzipping and parsing it, 0.07.) Callers only read answers."""
        body = response.read()
        answer = self._answers.pop(body, None)
        if answer is None:
            answer = xmlrpc.client.loads(body)[0]
            if len(self._answers) >= ANSWERS_KEPT:
                del self._answers[next(iter(self._answers))]
        self._answers[body] = answer
        return answer


def api_proxy(uri):
    return xmlrpc.client.ServerProxy(uri, transport=_Transport())


def succeeded(answer):
    """The value of a master API answer (code, message, value), or MasterError."""
    code, message, value = answer
    if code != 1:
        raise MasterError(message)
    return value
