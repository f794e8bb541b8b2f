"""turtlesim_node's table of each turtle's topics and services (node.TurtleInterfaces), which the publishing thread
publishes through while service threads spawn and kill turtles."""

import threading
from types import SimpleNamespace

from turtlesim.node import TurtleInterfaces


class Interface:
    """A turtle's interface whose publish can be held (until `go`), and that tells whether it was closed while a
    publish through it was under way (rospy then fails the publish)."""

    def __init__(self):
        self.inside, self.go = threading.Event(), threading.Event()
        self.go.set()
        self.published, self.closed, self.closed_during_a_publish = [], False, False
        self._publishing = False

    def publish(self, reading):
        self._publishing = True
        self.inside.set()
        assert self.go.wait(5)
        self.published.append(reading)
        self._publishing = False

    def close(self):
        self.closed = True
        self.closed_during_a_publish |= self._publishing


def reading(name):
    return SimpleNamespace(name=name)


def test_a_killed_turtle_is_withdrawn_only_once_its_publish_under_way_is_done():
    made = {}
    table = TurtleInterfaces(lambda name: made.setdefault(name, Interface()))
    table.sync({"turtle1", "doomed"})
    doomed = made["doomed"]
    doomed.go.clear()  # (the publishing thread loses the CPU in the middle of doomed's publish)
    publishing = threading.Thread(target=table.publish, args=([reading("turtle1"), reading("doomed")],))
    publishing.start()
    assert doomed.inside.wait(5)
    killing = threading.Thread(target=table.sync, args=({"turtle1"},))  # (the /kill service's thread)
    killing.start()
    killing.join(0.2)
    assert not doomed.closed
    doomed.go.set()
    publishing.join(5)
    killing.join(5)
    assert doomed.closed and not doomed.closed_during_a_publish
    table.publish([reading("turtle1"), reading("doomed")])  # the withdrawn turtle's reading goes nowhere
    assert len(doomed.published) == 1 and len(made["turtle1"].published) == 2


def test_spawned_turtles_are_made_once_and_killed_ones_closed():
    made = []
    table = TurtleInterfaces(lambda name: made.append((name, Interface())) or made[-1][1])
    table.sync({"turtle1"})
    table.sync({"turtle1", "turtle2"})
    table.sync({"turtle2"})
    assert [name for name, _ in made] == ["turtle1", "turtle2"]
    assert [interface.closed for _, interface in made] == [True, False]
