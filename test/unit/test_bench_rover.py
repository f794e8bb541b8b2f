"""The rover bench's own checks (bench/nav_clients.py, bench/nav_ceiling.py, bench/nav_messages.py): what they call
whole and right is, and what is not is caught; else the bench's "all right" would say nothing."""

import json
import math
import struct
import sys
from pathlib import Path

import cbor2
import genpy
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
import nav_clients  # noqa: E402
import nav_messages  # noqa: E402
from nav_ceiling import Frames  # noqa: E402

from rosbridge.protocol.encoded import TopicMessage  # noqa: E402


def bridge_frames(stream, compression, fragment_size=None):
    """The frames the bridge sends for the stream's message (stamped now), as bytes."""
    msg = stream.build()
    data = nav_messages.serialized(msg)
    cls = genpy.message.get_message_class(stream.type)
    return data, [bytes(f) for f in TopicMessage(stream.topic, cls, data, 0.0).frames(compression, fragment_size)]


@pytest.mark.parametrize("name", [s.name for s in nav_messages.STREAMS])
def test_every_stream_as_the_bridge_sends_it_is_whole_and_right(name):
    stream = nav_messages.BY_NAME[name]
    expected = nav_clients.Expected(stream)
    data, (text,) = bridge_frames(stream, "none")
    _, (binary,) = bridge_frames(stream, "cbor")
    assert nav_clients.difference(expected.msg, json.loads(text)["msg"]) is None
    assert nav_clients.difference(expected.msg, cbor2.loads(binary)["msg"]) is None
    assert expected.raw_difference(data) is None


def test_a_wrong_cell_point_range_or_word_is_caught():
    scan, diagnostics, cloud, grid = (
        nav_clients.Expected(nav_messages.BY_NAME[n]) for n in ("scan", "diagnostics", "points", "map")
    )

    def decoded(name, compression="none"):
        frame = bridge_frames(nav_messages.BY_NAME[name], compression)[1][0]
        return (json.loads(frame) if compression == "none" else cbor2.loads(frame))["msg"]

    msg = decoded("scan")
    nan_at = next(i for i, r in enumerate(scan.msg.ranges) if math.isnan(r))
    msg["ranges"][nan_at] = 1.5  # (a number where there was no return)
    assert "ranges" in nav_clients.difference(scan.msg, msg)
    msg = decoded("diagnostics")
    msg["status"][1]["message"] = msg["status"][1]["message"].encode().decode("latin-1")  # (mangled UTF-8)
    assert "status[1].message" in nav_clients.difference(diagnostics.msg, msg)
    msg = decoded("points", "cbor")
    msg["data"] = msg["data"][:-1] + bytes([msg["data"][-1] ^ 1])
    assert "other bytes" in nav_clients.difference(cloud.msg, msg)
    msg = decoded("map", "cbor")
    cells = bytearray(msg["data"].value)
    cells[123_456] = 100 if cells[123_456] != 100 else 0
    assert nav_clients.difference(grid.msg, {**msg, "data": cbor2.CBORTag(72, bytes(cells))}) == "data: other numbers"
    msg = decoded("map")
    msg["data"] = msg["data"][:-1]
    assert "items" in nav_clients.difference(grid.msg, msg)
    raw = bytearray(nav_messages.serialized(nav_messages.BY_NAME["map"].build()))
    raw[-1] ^= 1
    assert "differ" in grid.raw_difference(bytes(raw))


def test_nan_and_inf_may_come_as_null_but_nothing_else_stands_for_them():
    assert nav_clients.same_float("float32", math.nan, None) and nav_clients.same_float("float32", math.nan, math.nan)
    assert nav_clients.same_float("float64", -math.inf, None) and nav_clients.same_float("float64", math.inf, math.inf)
    assert not nav_clients.same_float("float64", math.inf, -math.inf)
    assert not nav_clients.same_float("float32", math.nan, 0.0)
    assert not nav_clients.same_float("float64", 1.0, None)
    assert nav_clients.same_float("float32", struct.unpack("<f", struct.pack("<f", 0.01))[0], 0.01)  # (as printed)
    assert not nav_clients.same_float("float64", 0.1, True)


def test_typed_arrays_are_read_by_their_tag_bits():
    assert list(nav_clients.typed_array(cbor2.CBORTag(85, struct.pack("<2f", 1.5, -2)))) == [1.5, -2.0]
    assert list(nav_clients.typed_array(cbor2.CBORTag(81, struct.pack(">2f", 1.5, -2)))) == [1.5, -2.0]  # big-endian
    assert list(nav_clients.typed_array(cbor2.CBORTag(77, struct.pack("<3h", 1, -2, 3)))) == [1, -2, 3]
    assert list(nav_clients.typed_array(cbor2.CBORTag(72, b"\xff\x00\x64"))) == [-1, 0, 100]
    with pytest.raises(ValueError):
        nav_clients.typed_array(cbor2.CBORTag(80, b"\0\0"))  # (a half float)


def test_the_ceiling_writes_each_push_stamp_where_the_bridges_bytes_have_their_stamps():
    now = 1_795_000_000.123456789
    for name in ("scan", "tf"):
        stream = nav_messages.BY_NAME[name]
        expected = nav_clients.Expected(stream)
        for compression in ("none", "cbor", "cbor-raw"):
            ((frame, text),) = Frames(stream, compression, None).stamped(now)
            assert text == (compression == "none")
            msg = json.loads(frame)["msg"] if text else cbor2.loads(frame)["msg"]
            if compression == "cbor-raw":
                assert expected.raw_difference(msg["bytes"]) is None
                stamp = expected.raw_stamp(msg["bytes"])
            else:
                assert nav_clients.difference(expected.msg, msg) is None
                stamp = expected.value_stamp(msg)
            assert stamp == pytest.approx(now, abs=1e-6)


def test_a_fragmented_message_is_put_together_even_when_its_total_is_a_fraction():
    """rosbridge_server 0.11.17 on Python 3 says total 552.17 for 552 parts."""
    stream = nav_messages.BY_NAME["fix"]
    record = nav_clients.Record({"fix": stream})
    client = nav_clients.Rosbridge(record)
    client.encodings["fix"] = "json"
    _, (text,) = bridge_frames(stream, "none")
    text = text.decode()
    parts = [text[i : i + 50] for i in range(0, len(text), 50)]
    for num, part in enumerate(parts):
        client.frame(
            json.dumps({"op": "fragment", "id": 0, "data": part, "num": num, "total": (len(text) - 1) / 50 + 1})
        )
    (arrival,) = record.arrivals["fix"]
    assert arrival[2] > len(text) and record.checks["fix"] == {"checked": 1, "wrong": 0, "first_wrong": None}


def test_fragments_of_two_messages_under_one_id_are_said_not_to_make_a_message():
    """rosbridge_server 0.11.17 numbers every fragmented message's parts from id 0, so two sent at once mix."""
    stream = nav_messages.BY_NAME["fix"]
    record = nav_clients.Record({"fix": stream})
    client = nav_clients.Rosbridge(record)
    client.encodings["fix"] = "json"
    text = bridge_frames(stream, "none")[1][0].decode()
    for num, part in enumerate([text[:40], '{"op": "publish", "to', text[80:]]):
        client.frame(json.dumps({"op": "fragment", "id": 0, "data": part, "num": num, "total": 3}))
    assert record.arrivals["fix"] == [] and record.statuses[0][1].startswith("{'op': 'undecodable'")
