"""The websocket transport: RFC 6455 without I/O, the connections on the event loop, their budgets."""
