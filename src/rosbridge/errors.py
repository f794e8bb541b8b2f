"""The one base class of every refusal that is the client's fault. Its text goes back to the client (a status
frame, a failed service_response or service call); any other exception is a bug of the bridge: logged with its
traceback and answered with a generic internal error."""


class ClientError(Exception):
    """A request the bridge refuses because of what the client sent or asked for."""


class RequestError(ClientError):
    """A malformed, unknown or forbidden request (a field, an op, a name, a limit)."""
