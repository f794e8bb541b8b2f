"""Who holds what: the clients that use each shared ROS object (a topic's publisher or subscriber). The first
holder makes the object, the last one to leave lets it go. Pure (no rospy), so it is tested directly."""


class Holders:
    def __init__(self):
        # name -> its holders, in the order they came: a tuple, replaced (never changed) as holders come and go, so
        # that a delivery may go through it while holders leave, without a copy for each message (subscribers.py)
        self.by_name = {}

    def add(self, name, holder):
        """Returns True when `name` had no holder before."""
        holders = self.by_name.get(name, ())
        if holder not in holders:
            self.by_name[name] = (*holders, holder)
        return not holders

    def discard(self, name, holder):
        """Returns True when `holder` was the last holder of `name`."""
        holders = self.by_name.get(name, ())
        if holder not in holders:
            return False
        rest = tuple(other for other in holders if other != holder)
        if rest:
            self.by_name[name] = rest
            return False
        del self.by_name[name]
        return True

    def holds(self, name, holder):
        return holder in self.by_name.get(name, ())

    def holders(self, name):
        return self.by_name.get(name, ())

    def names_of(self, holder):
        return [name for name, holders in self.by_name.items() if holder in holders]
