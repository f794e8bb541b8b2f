"""The parameter server, asked for Foxglove clients (foxglove/session.py) on a call thread (services.ServiceCalls.run):
every call here blocks on the master. Many names go to the master in one request (XML-RPC's system.multicall, which
rosgraph's servers offer): one request per name took 25 s, 16 s of the bridge's CPU and 14 s of the master's for
10,000 names; one multicall takes 0.3 s."""

import xmlrpc.client

import rosgraph
import rospy

from rosbridge.contract import DELETE
from rosbridge.errors import RequestError


def _master():
    return rosgraph.Master(rospy.get_name())


def get_parameters(names):
    """{name: value} of these parameters (a namespace's value is its dict), or of every one (names None) by its
    leaf name. Names the master does not have are left out."""
    master = _master()
    if names is None:
        return flatten(master.getParam("/"))
    answers = _each(master, [("getParam", name) for name in names])
    return {name: value for name, (code, _, value) in zip(names, answers) if code == 1}  # (else: not set)


def set_parameters(values):
    """Sets (or with DELETE, deletes) each; {name: value or DELETE} as the master has them now."""
    calls = (("deleteParam", name) if value is DELETE else ("setParam", name, value) for name, value in values.items())
    for (name, value), (code, text, _) in zip(values.items(), _each(_master(), calls)):
        if code != 1 and value is not DELETE:  # (deleting one that is not set is no error)
            raise RequestError(f"{name}: {text}")
    return values


def _each(master, calls):
    """The master's [code, text, value] for each (method, *args), asked in one request."""
    multicall = xmlrpc.client.MultiCall(master.handle)
    for method, *args in calls:
        getattr(multicall, method)(master.caller_id, *args)
    return list(multicall())


def flatten(tree, prefix="/"):
    """The master's tree under `prefix` (a dict of dicts) -> {leaf name: value}, as getParamNames lists them."""
    out = {}
    for key, value in tree.items():
        name = prefix + key
        if isinstance(value, dict) and value:
            out.update(flatten(value, name + "/"))
        else:
            out[name] = value
    return out
