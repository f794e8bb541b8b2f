"""The seams of contract.py, checked against what implements them: a protocol session (protocol.Session,
foxglove.FoxgloveSession) is what its connection calls (ProtocolSession) and what the ROS side calls (Client); a
connection (transport/connection.ClientConnection), and the tests' fake of it, is what a session may ask
(SessionHost)."""

import inspect

import pytest

from rosbridge.contract import Client, ProtocolSession, SessionHost
from rosbridge.globs import Globs
from rosbridge.protocol import Config, Session

from fakes import Host


def members(contract):
    """What a typing.Protocol asks for: its methods, its properties and its annotated attributes."""
    return sorted({*contract.__annotations__, *(name for name in vars(contract) if not name.startswith("_"))})


def mismatches(implementation, contract):
    """How `implementation` (a class, or an instance for the attributes set in __init__) fails `contract`: each
    method must take the contract's parameters, by name and in order (any more after them with defaults); each
    attribute or property must be there."""
    cls = implementation if inspect.isclass(implementation) else type(implementation)
    found = []
    for name in members(contract):
        asked = vars(contract).get(name)
        if not hasattr(implementation, name):
            found.append(f"{name}: missing")
        elif inspect.isfunction(asked):
            given = inspect.signature(getattr(cls, name))
            params, wanted = list(given.parameters.values()), list(inspect.signature(asked).parameters)
            if [param.name for param in params[: len(wanted)]] != wanted or any(
                param.default is inspect.Parameter.empty for param in params[len(wanted) :]
            ):
                found.append(f"{name}{given} is not {name}{inspect.signature(asked)}")
    return found


@pytest.mark.parametrize("contract", [ProtocolSession, Client], ids=lambda contract: contract.__name__)
def test_the_rosbridge_session_is_what_its_connection_and_the_ros_side_call(contract):
    session = Session(None, Config(), Host())  # (its backend is asked nothing here)
    assert mismatches(session, contract) == []


@pytest.mark.parametrize("contract", [ProtocolSession, Client], ids=lambda contract: contract.__name__)
def test_the_foxglove_session_is_what_its_connection_and_the_ros_side_call(contract):
    from rosbridge.foxglove import Catalog, FoxgloveSession

    class Quiet:  # (a backend that is asked only to watch the graph here)
        def watch_graph(self, listener):
            pass

    host = Host()
    session = FoxgloveSession(Quiet(), Config(), host, Catalog(Quiet(), Globs(), host.call_later, host.cancel_later))
    assert mismatches(session, contract) == []


def test_the_connection_and_the_fake_host_are_what_a_session_may_ask():
    from rosbridge.transport.connection import ClientConnection

    assert mismatches(ClientConnection, SessionHost) == []
    assert mismatches(Host(), SessionHost) == []


def test_a_method_missing_or_asked_otherwise_is_found():
    class Half:
        authenticated = holding = True

        def handle_text(self, text, depth=0):
            pass

        def handle_binary(self, payload):
            pass

        def take_frames(self):
            pass

    assert mismatches(Half, ProtocolSession) == [
        "backed_up: missing",
        "closed: missing",
        "handle_binary(self, payload) is not handle_binary(self, data: bytes) -> None",
        "take_frames(self) is not take_frames(self, most_bytes: int) -> list",
    ]
