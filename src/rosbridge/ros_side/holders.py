"""Who holds what: the clients that use each shared ROS object (a topic's publisher or subscriber). The first
holder makes the object, the last one to leave lets it go. Pure (no rospy), so it is tested directly."""


class Holders:
    def __init__(self):
        self._by_name = {}

    def add(self, name, holder):
        """Returns True when `name` had no holder before."""
        holders = self._by_name.setdefault(name, set())
        first = not holders
        holders.add(holder)
        return first

    def discard(self, name, holder):
        """Returns True when `holder` was the last holder of `name`."""
        holders = self._by_name.get(name)
        if holders is None or holder not in holders:
            return False
        holders.discard(holder)
        if holders:
            return False
        del self._by_name[name]
        return True

    def holds(self, name, holder):
        return holder in self._by_name.get(name, ())

    def holders(self, name):
        return tuple(self._by_name.get(name, ()))

    def names_of(self, holder):
        return [name for name, holders in self._by_name.items() if holder in holders]
