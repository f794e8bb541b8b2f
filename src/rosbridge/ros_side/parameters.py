"""The parameter server, asked for Foxglove clients (foxglove/session.py) on a call thread (services.ServiceCalls.run):
every call here blocks on the master."""

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
    values = {}
    for name in names:
        try:
            values[name] = master.getParam(name)
        except rosgraph.MasterError:  # (not set)
            continue
    return values


def set_parameters(values):
    """Sets (or with DELETE, deletes) each; {name: value or DELETE} as the master has them now."""
    master, done = _master(), {}
    for name, value in values.items():
        try:
            if value is DELETE:
                if master.hasParam(name):
                    master.deleteParam(name)
            else:
                master.setParam(name, value)
        except rosgraph.MasterError as error:
            raise RequestError(f"{name}: {error}") from None
        done[name] = value
    return done


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
