"""http/no_op_client.NoOpClient is a whole contract.Client, each method with the contract's parameters: the HTTP
endpoints' clients of the ROS side derive from it and define only what they take."""

import inspect

from rosbridge.contract import Client
from rosbridge.http.no_op_client import NoOpClient


def test_the_no_op_client_has_every_method_of_the_contract_and_does_nothing():
    names = [name for name in vars(Client) if not name.startswith("_")]
    assert names
    client = NoOpClient()
    for name in names:
        parameters = inspect.signature(getattr(Client, name)).parameters
        method = getattr(client, name)
        assert ["self", *inspect.signature(method).parameters] == list(parameters), name
        assert method(*(None for given in parameters if given not in ("self", "request_id"))) is None
    assert client.is_closed is False
