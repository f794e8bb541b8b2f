"""The base of the HTTP endpoints' own clients of the ROS side (a camera or cloud topic's subscription, the
master look-ups): a contract.Client whose methods do nothing, so that each overrides only what it takes."""


class NoOpClient:
    """A contract.Client that takes nothing: no messages, refusals, service requests (it provides no service) or
    status (nobody would read it)."""

    is_closed = False

    def deliver(self, read):
        pass

    def ros_refused(self, op, name, text):
        pass

    def request_service(self, call_id, service, args):
        pass

    def status(self, level, msg, request_id=None):
        pass
