"""rosauth: the MAC check of the `auth` op, and of the HTTP endpoints' query strings (UrlMacs)."""

import hashlib
import hmac
import math

MAX_REMEMBERED = 10_000  # MACs whose t lay ahead that UrlMacs remembers (only valid MACs: made with the secret)


def mac_is_valid(auth, secret, now, time_delta):
    """rosauth's check: mac == hex(sha512(secret+client+dest+rand+int(t)+level+int(end))), int(t)
    within time_delta seconds of now (a negative delta skips that check) and int(end) still in the future."""
    if secret is None or not (math.isfinite(auth["t"]) and math.isfinite(auth["end"])):
        return False
    t, end = int(auth["t"]), int(auth["end"])  # what the MAC signs: a t of T.999 must not last a second longer
    if time_delta >= 0 and abs(t - now) >= time_delta:
        return False
    if end <= now:
        return False
    text = "".join((secret, auth["client"], auth["dest"], auth["rand"], str(t), auth["level"], str(end)))
    expected = hashlib.sha512(text.encode()).hexdigest()
    return hmac.compare_digest(expected.encode(), auth["mac"].lower().encode())


class UrlMacs:
    """The check of MACs that come in URLs, which logs, browser histories and Referer headers keep for anyone to
    replay: one is valid time_delta seconds in all, from its t or, when its t lay ahead of now (a clock ahead of
    ours), from when it was first seen. mac_is_valid alone lets a t ahead by up to time_delta keep it valid twice
    as long. (The websocket `auth` op keeps rosauth's rule: README, Security.)"""

    def __init__(self, time_delta):
        self.time_delta = time_delta
        self._first_seen = {}  # mac -> (when first seen, its t), for those whose t lay ahead then

    def valid(self, auth, secret, now):
        if not mac_is_valid(auth, secret, now, self.time_delta):
            return False
        mac = auth["mac"].lower()
        if mac in self._first_seen:
            return now - self._first_seen[mac][0] < self.time_delta
        if self.time_delta >= 0 and int(auth["t"]) > now:
            self._forget(now)
            self._first_seen[mac] = (now, int(auth["t"]))
        return True

    def _forget(self, now):
        """Forgets the MACs mac_is_valid refuses by now, then the oldest beyond MAX_REMEMBERED."""
        for mac, (_, t) in list(self._first_seen.items()):
            if t + self.time_delta <= now:
                del self._first_seen[mac]
        while len(self._first_seen) >= MAX_REMEMBERED:
            del self._first_seen[next(iter(self._first_seen))]
