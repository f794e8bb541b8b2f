"""The dead-man stop (README, Dead-man stop): a robot is stopped when the client driving it goes silent."""

import time

import tornado.ioloop


class DriverLeases:
    """The dead-man stop for a driving client that goes silent (a phone that lost its Wi-Fi sends no FIN: its
    connection only looks open). A client that drives (Backend.drives) holds a lease that anything it sends
    renews; silent for half of `timeout`, it is pinged (a live client answers at once); silent for `timeout`,
    its velocity topics get one zero message each (Backend.stop_driving) until it drives again. A client that
    leaves is stopped by the backend at once (RosBackend's stop_drivers_leaving). Checked every timeout / 4 while
    anyone drives, and at the moment a silent driver's lease ends; while nobody drives, not at all (an idle
    bridge left running for days is not woken four times a second): the backend's driving_began starts it."""

    def __init__(self, timeout):
        self.timeout, self.bridge = timeout, None
        self._loop = tornado.ioloop.IOLoop.current()
        self._timer = None  # the next check, while anyone drives

    def serve(self, bridge):
        """The bridge whose clients' leases are kept (made after its backend, which tells driving_began)."""
        self.bridge = bridge

    def driving_began(self):
        """A client began to drive (on the loop): its lease is checked from now on."""
        if self._timer is None and self.bridge is not None:
            self._timer = self._loop.call_later(self.timeout / 4, self._check)

    def _check(self):
        self._timer = None
        now, backend = time.monotonic(), self.bridge.backend
        wait, driving = self.timeout / 4, False
        for client in self.bridge.clients:
            if not backend.drives(client.session):
                continue
            silent = client.silent_for(now)
            if silent >= self.timeout:
                backend.stop_driving(client.session)
                continue
            driving = True
            if silent >= self.timeout / 2:
                client.ping()
            if silent > 0:
                wait = min(wait, self.timeout - silent)
        if driving:
            self._timer = self._loop.call_later(wait, self._check)
