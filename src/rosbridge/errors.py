"""The one base class of every refusal that is the client's fault. Its text goes back to the client (a status
frame, a failed service_response or service call); any other exception is a bug of the bridge: logged with its
traceback and answered with a generic internal error."""

import logging
import sys
import time


class ClientError(Exception):
    """A request the bridge refuses because of what the client sent or asked for."""


class RequestError(ClientError):
    """A malformed, unknown or forbidden request (a field, an op, a name, a limit)."""


_last_logged = {}


def log_bug(what, error=None, every=60.0):
    """Logs `error` (default: the exception being handled) with its traceback, at most once per `every`
    seconds for each place it comes from, so that a client repeating a bad request cannot fill the disk."""
    error = error if error is not None else sys.exc_info()[1]
    tb = error.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    kind = (what, type(error).__name__) + ((tb.tb_frame.f_code.co_filename, tb.tb_lineno) if tb else ())
    now = time.monotonic()
    if now - _last_logged.get(kind, -every) >= every:
        _last_logged[kind] = now
        logging.getLogger("rosbridge").error("internal error: %s", what, exc_info=error)


def refusal_text(error, what):
    """The text telling a client why the ROS side refused; an error that is not the client's is logged too."""
    if not isinstance(error, (ClientError, ValueError)):  # (rospy refuses illegal names with ValueError)
        log_bug(what, error)
    return str(error) or repr(error)
