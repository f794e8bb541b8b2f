"""The rover bench's clients (bench/nav_bench.py), one per process, each subscribed on one connection to some of
the rover's streams (nav_messages.STREAMS), as a page or a script subscribes:

  rosbridge  a rosbridge client (Tornado's websocket) of this bridge, the reference or the ceiling; each stream
             given as NAME[:ENCODING[:FRAGMENT_SIZE]]: ENCODING json (compression none, what roslibjs asks by
             default; throttle_rate and queue_length 0 as roslibjs sends them), cbor or cbor-raw; a fragmented
             message is put together from its fragments
  foxglove   a client of foxglove_bridge (foxglove_protocol.py): each message as its ROS bytes

Every message is decoded on arrival, as a client must to use it, and checked against what the generator
published: every field but the header's seq and stamp (the map's 16 million cells and the cloud's points
included; a float NaN or inf may come as null in JSON, where it has no number for them); raw ROS bytes byte for
byte. Decoded small messages are compared field by field for the first 20 of each stream, then one in 10 (a
Python walk through 50 TF frames at 100 Hz would make this client the slow end); every big one, and every raw one.
For each message it records when it arrived (wall time, at its last frame), its stamp and its size on the wire.

Prints READY once subscribed, and `GOT <stream> <n>` when the n-th message of a latched stream (tf_static, map)
arrives (the first of the others). Commands on stdin: `result` prints `RESULT <json>`: for each stream, when it was
asked for, [[arrived, stamp, bytes], ...], how many messages were checked and how many were not right, with the
first difference; the status ops received (their first 20); `quit`."""

import argparse
import asyncio
import base64
import json
import math
import struct
import sys
import time
from array import array

import cbor2
import foxglove_protocol
import nav_messages

import stats

CHECK_ALL, CHECK_EVERY = 20, 10  # decoded messages compared field by field: the first 20 of a stream, then 1 in 10
ARRAY_CODES = {
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}  # ROS -> Python's array module


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("role", choices=["rosbridge", "foxglove"])
    p.add_argument("--url", required=True)
    p.add_argument("streams", nargs="+", help="NAME[:ENCODING[:FRAGMENT_SIZE]] (foxglove: NAME)")
    a = p.parse_args()
    asyncio.run(run(a))


async def run(a):
    asked = [parse(item) for item in a.streams]
    record = Record({name: nav_messages.BY_NAME[name] for name, _, _ in asked})
    if a.role == "foxglove":
        client = foxglove_protocol.Client(
            lambda topic, payload, size, arrived: record.raw(nav_messages.BY_TOPIC[topic].name, payload, size, arrived),
            record.status,
        )
        await client.connect(a.url)
        await client.subscribe([nav_messages.BY_NAME[name].topic for name, _, _ in asked], timeout=60)
        for name, _, _ in asked:
            record.asked[name] = time.time()
    else:
        client = Rosbridge(record)
        await client.connect(a.url)
        for name, encoding, fragment_size in asked:
            await client.subscribe(nav_messages.BY_NAME[name], encoding, fragment_size)
    print("READY", flush=True)
    await asyncio.to_thread(stats.commands, {"result": record.result})
    client.close()


def parse(item):
    name, encoding, fragment_size = (item.split(":") + [None, None])[:3]
    if name not in nav_messages.BY_NAME:
        raise SystemExit(f"no stream {name!r}: {', '.join(nav_messages.BY_NAME)}")
    if encoding not in (None, "json", "cbor", "cbor-raw"):
        raise SystemExit(f"{item}: the encoding is json, cbor or cbor-raw")
    return name, encoding or "json", int(fragment_size) if fragment_size else None


class Rosbridge:
    """A rosbridge v2 client: JSON text frames (fragments put together), CBOR binary frames."""

    def __init__(self, record):
        self.record = record
        self.parts = {}  # fragment id -> {num: data}, and their bytes so far
        self.encodings = {}  # stream name -> its encoding
        self.ws = None

    async def connect(self, url):
        from tornado.websocket import websocket_connect

        self.ws = await websocket_connect(url, max_message_size=64 << 20, on_message_callback=self.frame)

    async def subscribe(self, stream, encoding, fragment_size):
        op = {
            "op": "subscribe",
            "id": f"subscribe:{stream.topic}",
            "topic": stream.topic,
            "type": stream.type,
            "compression": "none" if encoding == "json" else encoding,
            "throttle_rate": 0,
            "queue_length": 0,
        }
        if fragment_size:
            op["fragment_size"] = fragment_size
        self.encodings[stream.name] = encoding
        self.record.asked[stream.name] = time.time()
        await self.ws.write_message(json.dumps(op))

    def frame(self, frame, size=None):
        arrived = time.time()
        if frame is None:
            self.record.status({"op": "closed"})
            return
        size = size or len(frame)
        try:
            op = cbor2.loads(frame) if isinstance(frame, bytes) else json.loads(frame)
        except ValueError as error:  # (e.g. the parts of two messages under one fragment id: the reference's)
            self.record.status({"op": "undecodable", "bytes": size, "error": str(error)[:100]})
            return
        kind = op.get("op")
        if kind == "fragment":
            parts, got = self.parts.setdefault(op["id"], ({}, [0]))
            parts[op["num"]] = op["data"]
            got[0] += size
            if len(parts) == int(op["total"]):  # (the reference's total is a fraction: Python 3's / for //)
                del self.parts[op["id"]]
                self.frame("".join(parts[n] for n in sorted(parts)), got[0])
        elif kind == "publish":
            stream = nav_messages.BY_TOPIC.get(op.get("topic"))
            if stream is None:
                return
            if self.encodings.get(stream.name) == "cbor-raw":  # (the ROS bytes, and when the server got them)
                self.record.raw(stream.name, op["msg"]["bytes"], size, arrived)
            else:
                self.record.value(stream.name, op.get("msg"), size, arrived)
        else:
            self.record.status(op)

    def close(self):
        self.ws.close()


class Record:
    """What arrived of each stream, and whether it was right."""

    def __init__(self, streams):
        self.expected = {name: Expected(stream) for name, stream in streams.items()}
        self.arrivals = {name: [] for name in streams}
        self.asked = {}
        self.checks = {name: {"checked": 0, "wrong": 0, "first_wrong": None} for name in streams}
        self.statuses = []

    def raw(self, name, payload, size, arrived):
        expected = self.expected[name]
        self._arrived(name, arrived, expected.raw_stamp(payload), size, expected.raw_difference(payload))

    def value(self, name, msg, size, arrived):
        expected, checked = self.expected[name], self._checks(name)
        try:
            stamp = expected.value_stamp(msg)
            wrong = difference(expected.msg, msg) if checked else None
        except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
            stamp, wrong, checked = None, f"not a {expected.msg._type}: {type(error).__name__} {error}", True
        self._arrived(name, arrived, stamp, size, wrong, checked)

    def _checks(self, name):
        """Whether to compare this decoded message field by field (Python takes about a millisecond for 50 TF
        frames, 100 times a second: enough to make the client the slow end): the first CHECK_ALL of each stream,
        then one in CHECK_EVERY; every one of the big ones (a byte-string compare)."""
        n = len(self.arrivals[name])
        return n < CHECK_ALL or n % CHECK_EVERY == 0 or self.expected[name].big

    def _arrived(self, name, arrived, stamp, size, wrong, checked=True):
        self.arrivals[name].append((arrived, stamp, size))
        check = self.checks[name]
        check["checked"] += checked
        if wrong:
            check["wrong"] += 1
            check["first_wrong"] = check["first_wrong"] or wrong[:300]
        n = len(self.arrivals[name])
        if n == 1 or not self.expected[name].hz:
            print(f"GOT {name} {n}", flush=True)

    def status(self, op):
        self.statuses.append((time.time(), str(op)[:300]))

    def result(self):
        return {
            "streams": {
                name: {"asked": self.asked.get(name), "arrivals": list(self.arrivals[name]), **self.checks[name]}
                for name in self.arrivals
            },
            "statuses": self.statuses[:20],
            "status_count": len(self.statuses),
        }


class Expected:
    """What a stream's messages must hold: the message as the generator built it (for decoded values), and its
    ROS bytes with the sentinel stamps (nav_messages.sentinel_bytes, for raw ones)."""

    def __init__(self, stream):
        self.hz = stream.hz
        self.msg = stream.build()
        self.raw_bytes, self.stamp_places = nav_messages.sentinel_bytes(self.msg)
        self.big = len(self.raw_bytes) >= 1_000_000
        self.has_header = self.msg._slot_types[0] == "std_msgs/Header"  # (whose seq rospy sets)
        self.stamp_path = _first_header(self.msg) + ["stamp"]

    def raw_stamp(self, payload):
        if len(payload) < self.stamp_places[0] + 8:
            return None
        secs, nsecs = struct.unpack_from("<II", payload, self.stamp_places[0])
        return secs + nsecs / 1e9

    def raw_difference(self, payload):
        got = bytearray(payload)
        if len(got) != len(self.raw_bytes):
            return f"{len(got)} ROS bytes, not {len(self.raw_bytes)}"
        for at in self.stamp_places:
            got[at : at + 8] = nav_messages.SENTINEL_RAW
        if self.has_header:
            got[0:4] = bytes(4)
        if got != self.raw_bytes:
            at = next(i for i, (x, y) in enumerate(zip(got, self.raw_bytes)) if x != y)
            return f"ROS bytes differ from byte {at} on"
        return None

    def value_stamp(self, msg):
        for key in self.stamp_path:
            msg = msg[key]
        return msg["secs"] + msg["nsecs"] / 1e9


def _first_header(msg):
    """The path (keys and indices) to the first std_msgs/Header in msg (TF's: its first transform's)."""
    for name, kind in zip(msg.__slots__, msg._slot_types):
        if kind == "std_msgs/Header":
            return [name]
        if "/" in kind:
            value = getattr(msg, name)
            inner = _first_header(value[0] if kind.endswith("]") else value) if value else None
            if inner is not None:
                return [name] + ([0] if kind.endswith("]") else []) + inner
    return None


# ---- a decoded message against the one published --------------------------------------------------------


def difference(expected, got, path=""):
    """Where the decoded message `got` (JSON or CBOR values) differs from the genpy message `expected`, or None.
    Not compared: a header's seq and stamp (the publisher's, per message)."""
    if not isinstance(got, dict):
        return f"{path or 'the message'}: {type(got).__name__}, not a message"
    for name, kind in zip(expected.__slots__, expected._slot_types):
        where = f"{path}.{name}" if path else name
        if name not in got:
            return f"{where}: missing"
        if kind == "std_msgs/Header":  # (its frame only)
            frame = got[name].get("frame_id")
            wrong = None if frame == getattr(expected, name).frame_id else f"{where}.frame_id: {frame!r}"
        else:
            wrong = field_difference(kind, getattr(expected, name), got[name], where)
        if wrong:
            return wrong
    return None


def field_difference(kind, want, got, where):
    base, _, size = kind.partition("[")
    if size:
        return array_difference(base, want, got, where)
    if base in ("float32", "float64"):
        return None if same_float(base, want, got) else f"{where}: {got!r}, not {want!r}"
    if base in ("time", "duration"):
        return None if (got["secs"], got["nsecs"]) == (want.secs, want.nsecs) else f"{where}: {got!r}"
    if "/" in base:
        return difference(want, got, where)
    if base == "bool":
        return None if bool(got) == bool(want) else f"{where}: {got!r}, not {want!r}"
    return None if got == want else f"{where}: {str(got)[:80]!r}, not {str(want)[:80]!r}"


def array_difference(base, want, got, where):
    if base in ("uint8", "char"):
        got = as_bytes(got)
        want = want if isinstance(want, bytes) else bytes(want)
        return (
            None
            if got == want
            else f"{where}: {len(got)} bytes, not the {len(want)} published"
            + ("" if len(got) != len(want) else " (same length, other bytes)")
        )
    if isinstance(got, cbor2.CBORTag):
        got = typed_array(got)
    if len(got) != len(want):
        return f"{where}: {len(got)} items, not {len(want)}"
    if base in ARRAY_CODES and not base.startswith("float"):
        code = ARRAY_CODES[base]
        want = _from_bytes(code, want) if isinstance(want, bytes) else array(code, want)
        return None if array(code, got) == want else f"{where}: other numbers"
    for i, (w, g) in enumerate(zip(want, got)):
        wrong = field_difference(base, w, g, f"{where}[{i}]")
        if wrong:
            return wrong
    return None


def _from_bytes(code, data):
    values = array(code)
    values.frombytes(data)
    return values


def same_float(base, want, got):
    """A float as published and as decoded: NaN and inf may come as null (JSON has no number for them)."""
    if not math.isfinite(want):
        return got is None or (isinstance(got, float) and (math.isnan(got) if math.isnan(want) else got == want))
    if not isinstance(got, (int, float)) or isinstance(got, bool):
        return False
    if base == "float32":
        return struct.pack("<f", want) == struct.pack("<f", got)
    return float(got) == want


def as_bytes(got):
    """A uint8[] as a client gets it: base64 text (JSON), a byte string or an RFC 8746 uint8 array (CBOR)."""
    if isinstance(got, str):
        return base64.b64decode(got)
    if isinstance(got, cbor2.CBORTag):
        return bytes(got.value)
    return bytes(got)


def typed_array(tag):
    """An RFC 8746 typed array (CBOR tags 64-87: bit 4 float, bit 3 signed, bit 2 little-endian, bits 0-1 the
    size) as an array of its numbers."""
    bits = tag.tag - 64
    if not 0 <= bits < 24 or (bits & 0x10 and (bits & 3) in (0, 3)):
        raise ValueError(f"CBOR tag {tag.tag} is not a typed array this client reads")
    size = bits & 3
    code = "efdx"[size] if bits & 0x10 else ("bhiq" if bits & 0x08 else "BHIQ")[size]
    values = _from_bytes(code, bytes(tag.value))
    if values.itemsize > 1 and bool(bits & 0x04) != (sys.byteorder == "little"):
        values.byteswap()
    return values


if __name__ == "__main__":
    main()
