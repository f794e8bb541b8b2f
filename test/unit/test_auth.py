"""rosauth's MAC check (auth.mac_is_valid, the `auth` op's) and UrlMacs (the HTTP endpoints' query strings): a MAC
in a URL is valid auth_time_delta seconds in all, however far ahead of the bridge's clock its t lay."""

import hashlib

from rosbridge.auth import UrlMacs, mac_is_valid

SECRET, DELTA, NOW = "s3cret", 5.0, 1_700_000_000.0


def auth(t, end=None, rand="r"):
    end = t + 60 if end is None else end
    fields = {"client": "c", "dest": "d", "rand": rand, "t": t, "level": "admin", "end": end}
    text = f"{SECRET}c d{rand}{int(t)}admin{int(end)}".replace(" ", "")
    return {**fields, "mac": hashlib.sha512(text.encode()).hexdigest().upper()}


def test_the_op_keeps_rosauths_rule_t_within_delta_either_way():
    ahead = auth(NOW + 4)
    assert mac_is_valid(ahead, SECRET, NOW, DELTA) and mac_is_valid(ahead, SECRET, NOW + 8.9, DELTA)
    assert not mac_is_valid(ahead, SECRET, NOW + 9, DELTA)
    assert not mac_is_valid(auth(NOW - 5), SECRET, NOW, DELTA)
    assert not mac_is_valid({**auth(NOW), "rand": "other"}, SECRET, NOW, DELTA)


def test_a_url_whose_t_lies_ahead_is_valid_delta_from_its_first_use():
    """mac_is_valid alone: 9 s (t 4 s ahead, first used at NOW)."""
    macs, ahead = UrlMacs(DELTA), auth(NOW + 4)
    assert macs.valid(ahead, SECRET, NOW) and macs.valid(ahead, SECRET, NOW + 4.9)
    assert not macs.valid(ahead, SECRET, NOW + 5) and not macs.valid(ahead, SECRET, NOW + 8.9)


def test_a_url_whose_t_is_past_is_valid_delta_from_its_t():
    macs, past = UrlMacs(DELTA), auth(NOW - 1)
    assert macs.valid(past, SECRET, NOW) and macs.valid(past, SECRET, NOW + 3.9)
    assert not macs.valid(past, SECRET, NOW + 4)
    assert not macs.valid(auth(NOW), "guess", NOW)


def test_a_negative_delta_still_checks_nothing_of_time():
    macs = UrlMacs(-1)
    assert macs.valid(auth(NOW + 1000), SECRET, NOW) and macs.valid(auth(NOW + 1000), SECRET, NOW + 1050)


def test_what_is_remembered_is_forgotten_once_refused_anyway_and_is_bounded(monkeypatch):
    monkeypatch.setattr("rosbridge.auth.MAX_REMEMBERED", 3)
    macs = UrlMacs(DELTA)
    for i in range(5):
        assert macs.valid(auth(NOW + 2, rand=str(i)), SECRET, NOW)
    assert len(macs._first_seen) == 3
    assert macs.valid(auth(NOW + 20, rand="later"), SECRET, NOW + 16)  # the others' t + delta has passed
    assert len(macs._first_seen) == 1


def test_t_and_end_count_as_the_whole_seconds_the_mac_signs():
    """The MAC signs int(t) and int(end): a t of T.99999 is the MAC of T, valid delta seconds from T, not T + 1."""
    late, macs = auth(NOW + 0.99999), UrlMacs(DELTA)
    assert mac_is_valid(late, SECRET, NOW + DELTA - 0.01, DELTA) and macs.valid(late, SECRET, NOW + DELTA - 0.01)
    assert not mac_is_valid(late, SECRET, NOW + DELTA, DELTA) and not macs.valid(late, SECRET, NOW + DELTA + 0.5)
    ending = auth(NOW, end=NOW + 10.9)  # (a delta of 20: only end decides)
    assert mac_is_valid(ending, SECRET, NOW + 9.9, 20) and not mac_is_valid(ending, SECRET, NOW + 10.5, 20)
