"""The dead-man stop (README, Dead-man stop): a robot is stopped when the client driving it goes silent."""

import time

import tornado.ioloop


class DriverLeases:
    """The dead-man stop for a driving client that goes silent (a phone that lost its Wi-Fi sends no FIN: its
    connection only looks open). A client that drives (Backend.drives) holds a lease that anything it sends
    renews; silent for half of `timeout`, it is pinged (a live client answers at once); silent for `timeout`,
    its velocity topics get one zero message each (Backend.stop_driving) until it drives again. A client that
    leaves is stopped by the backend at once (RosBackend's stop_drivers_leaving). Checked every timeout / 4, and
    at the moment a silent driver's lease ends."""

    def __init__(self, bridge, timeout):
        self.bridge, self.timeout = bridge, timeout
        self._loop = tornado.ioloop.IOLoop.current()

    def start(self):
        self._check()

    def _check(self):
        now, backend = time.monotonic(), self.bridge.backend
        wait = self.timeout / 4
        for client in self.bridge.clients:
            if not backend.drives(client.session):
                continue
            silent = client.silent_for(now)
            if silent >= self.timeout:
                backend.stop_driving(client.session)
                continue
            if silent >= self.timeout / 2:
                client.ping()
            if silent > 0:
                wait = min(wait, self.timeout - silent)
        self._loop.call_later(wait, self._check)
