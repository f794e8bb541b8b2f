"""rosauth: the MAC check of the `auth` op."""
import hashlib
import hmac
import math


def mac_is_valid(auth, secret, now, time_delta):
    """rosauth's check: mac == hex(sha512(secret+client+dest+rand+int(t)+level+int(end))), t within
    time_delta seconds of now (a negative delta skips that check) and end still in the future."""
    if secret is None or not (math.isfinite(auth["t"]) and math.isfinite(auth["end"])):
        return False
    if time_delta >= 0 and abs(auth["t"] - now) >= time_delta:
        return False
    if auth["end"] <= now:
        return False
    text = "".join((secret, auth["client"], auth["dest"], auth["rand"], str(int(auth["t"])), auth["level"],
                    str(int(auth["end"]))))
    expected = hashlib.sha512(text.encode()).hexdigest()
    return hmac.compare_digest(expected.encode(), auth["mac"].lower().encode())
