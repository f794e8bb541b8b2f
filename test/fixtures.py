"""The one factory of bridge fixtures, for test/integration and test/browser: a bridge node started for a module or
a test, and stopped after it whatever the tests did."""

import pytest

from harness import start_bridge


class From:
    """A setting whose value is a fixture's (or the test's parameter's), set up before the bridge:
    bag_folder=From("bag_folder"), address=From("address"); with a file name, that file of the fixture's folder:
    certfile=From("tls_folder", "cert.pem")."""

    def __init__(self, fixture, file=None):
        self.fixture, self.file = fixture, file

    def value(self, request):
        value = request.getfixturevalue(self.fixture)
        return value / self.file if self.file else value


class Bridge:
    """A running bridge node: its Proc (log, stop), port and page URL. start() runs it again, with the same name,
    settings and port, after the test stopped it (a restart, as its clients see one)."""

    def __init__(self, ros, node_name, settings):
        self._ros, self._node_name, self._settings = ros, node_name, settings
        self.proc, self.port = start_bridge(ros, node_name=node_name, **settings)

    @property
    def url(self):
        return f"http://127.0.0.1:{self.port}/"

    def start(self):
        self.proc, _ = start_bridge(self._ros, node_name=self._node_name, **{**self._settings, "port": self.port})


def bridge_fixture(node_name="rosbridge_websocket", *, scope="module", yields="port", needs=(), **settings):
    """A fixture running a bridge node with these settings (start_bridge's: max_fds too), stopped after its scope
    even when a test failed. Give each bridge that runs beside others its own node_name.
    - scope: "module", shared by the module's tests; "function", a bridge of the test's own (one it stops or
      restarts, or one whose settings only that test needs).
    - yields: "port"; "url", the page's (http://127.0.0.1:port/); "bridge", the Bridge (its Proc for the log or
      the CPU, start() for a restart).
    - needs: fixtures to set up before the bridge starts (and so to tear down after it stops), e.g. ("sim",).
    - a setting given as From(...) takes a fixture's value."""
    if yields not in ("port", "url", "bridge"):
        raise ValueError(f"yields={yields!r}: one of port, url, bridge")

    @pytest.fixture(scope=scope)
    def bridge(ros, request):
        for name in needs:
            request.getfixturevalue(name)
        values = {key: value.value(request) if isinstance(value, From) else value for key, value in settings.items()}
        running = Bridge(ros, node_name, values)
        try:
            yield running if yields == "bridge" else getattr(running, yields)
        finally:  # (the Proc running now: a restart's, if the test made one)
            running.proc.stop()

    return bridge
