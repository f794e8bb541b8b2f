"""A live fuzz run: 10,000 frames (valid, malformed and hostile, from a seeded generator) through two websocket
clients at once against a real bridge on the private roscore. The bridge must stay up with bounded memory,
answer every bad frame with one `status` error (carrying the frame's id when it had a usable one), answer
every service call, and still publish and subscribe afterwards on the fuzzed connection and on a fresh one."""

import asyncio
import json
import random
import time

import pytest
from tornado.websocket import websocket_connect

from bridge_client import WsClient
from fixtures import bridge_fixture
from harness import ProcStat, node_pid, wait_for

pytestmark = pytest.mark.slow  # (deselect with -m 'not slow' for a quick run)

FRAMES_PER_CLIENT = 5_000
BATCH = 250  # frames sent before waiting for their answers (keeps the bridge's per-client queue from dropping)
MAX_MESSAGE_SIZE = 100_000
TOPIC = "/fuzz/chatter"

fuzz_bridge = bridge_fixture("fuzz_bridge", yields="bridge", max_message_size=MAX_MESSAGE_SIZE)


class Plan:
    """What one frame must bring back: an error with this id ("error", id), an error without id
    ("error", None), a service_response with this id and result ("response", id, ok), or nothing."""

    def __init__(self, frame, expect):
        self.frame, self.expect = frame, expect


def generate(rng, client):
    """FRAMES_PER_CLIENT frames for one client; ids are unique per client."""
    valid_publish = {"op": "publish", "topic": TOPIC, "msg": {"data": "x"}}
    makers = []

    def maker(weight):
        def register(fn):
            makers.append((weight, fn))
            return fn

        return register

    def junk_text(n):
        return "".join(rng.choice('{}[]":,0123456789abcnul\\ \u00e9\u4e2d\U0001f600') for _ in range(n))

    @maker(12)
    def publish(i):
        return Plan({**valid_publish, "msg": {"data": junk_text(rng.randint(0, 40))}}, None)

    @maker(5)
    def get_time(i):
        return Plan(
            {"op": "call_service", "service": "/rosapi/get_time", "id": f"{client}:{i}"},
            ("response", f"{client}:{i}", True),
        )

    @maker(3)
    def missing_service(i):
        return Plan(
            {"op": "call_service", "service": f"/fuzz/none_{i}", "id": f"{client}:{i}"},
            ("response", f"{client}:{i}", False),
        )

    @maker(3)
    def subscribe_unsubscribe(i):
        op = rng.choice(["subscribe", "unsubscribe"])
        return Plan(
            {"op": op, "topic": "/fuzz/sub", "type": "std_msgs/String"}
            if op == "subscribe"
            else {"op": op, "topic": "/fuzz/sub"},
            None,
        )

    @maker(2)
    def fragmented_call(i):
        text = json.dumps({"op": "call_service", "service": "/rosapi/get_time", "id": f"{client}:{i}"})
        cut = rng.randint(1, len(text) - 1)
        parts = [text[:cut], text[cut:]]
        return [
            Plan({"op": "fragment", "id": f"frag:{client}:{i}", "data": part, "num": n, "total": 2}, None)
            for n, part in enumerate(parts)
        ][:-1] + [
            Plan(
                {"op": "fragment", "id": f"frag:{client}:{i}", "data": parts[1], "num": 1, "total": 2},
                ("response", f"{client}:{i}", True),
            )
        ]

    @maker(6)
    def truncated_json(i):
        text = json.dumps({**valid_publish, "id": f"{client}:{i}"})
        return Plan(text[: rng.randint(0, len(text) - 1)], ("error", None))

    @maker(4)
    def junk(i):
        return Plan(junk_text(rng.randint(1, 200)), "maybe-error")  # junk may happen to be valid JSON

    @maker(3)
    def not_an_object(i):
        return Plan(
            rng.choice(["42", '"op"', "[1,2]", "null", "true", "-1e999", '[{"op":"publish"}]']), ("error", None)
        )

    @maker(6)
    def unknown_op(i):
        return Plan(
            {"op": rng.choice(["", "PUBLISH", "pub", "status", "\u00fcber", "x" * 500]), "id": f"{client}:{i}"},
            ("error", f"{client}:{i}"),
        )

    @maker(10)
    def wrong_field(i):
        op, field, value = rng.choice(
            [
                ("publish", "topic", 5),
                ("publish", "msg", "text"),
                ("publish", "msg", [1]),
                ("subscribe", "topic", None),
                ("subscribe", "throttle_rate", "fast"),
                ("subscribe", "queue_length", 1.5),
                ("subscribe", "compression", "zip"),
                ("call_service", "args", "x"),
                ("call_service", "service", {"a": 1}),
                ("advertise", "type", ["std_msgs/String"]),
                ("set_level", "level", "loud"),
                ("fragment", "num", -1),
                ("png", "data", "not base64!"),
                ("advertise", "latch", "yes"),
                ("unsubscribe", "bogus_field", 1),
                ("subscribe", "type", "no_such_pkg/Nothing"),
                ("publish", "msg", {"data": 5}),
                ("publish", "msg", {"nope": "x"}),
                ("advertise", "type", "geometry_msgs/Twist"),  # the bridge already publishes TOPIC as a String
                ("call_service", "timeout", -1),
                ("subscribe", "fragment_size", 0),
            ]
        )
        base = {
            "publish": {**valid_publish},
            "subscribe": {"topic": "/fuzz/sub", "type": "std_msgs/String"},
            "call_service": {"service": "/rosapi/get_time"},
            "advertise": {"topic": TOPIC, "type": "std_msgs/String"},
            "set_level": {"level": "error"},
            "fragment": {"data": "{}", "num": 0, "total": 1},
            "png": {"data": ""},
            "unsubscribe": {"topic": "/fuzz/sub"},
        }[op]
        frame = {**base, "op": op, "id": f"{client}:{i}", field: value}
        if op == "fragment":
            frame["id"] = f"{client}:{i}"
        return Plan(frame, ("error", f"{client}:{i}"))

    @maker(4)
    def hostile_numbers(i):
        # (number, what an unknown op / a throttle_rate / a timeout with it must bring back)
        number, *outcomes = rng.choice(
            [
                ("NaN", ("error", None), "error", "error"),
                ("Infinity", ("error", None), "error", "response"),
                ("-Infinity", ("error", None), "error", "error"),
                ("1e999", ("error", None), "error", "response"),
                ("1" * 4400, ("error", None), ("error", None), ("error", None)),  # over Python's int digit limit
                ("-0", ("error", 0), None, "error"),
            ]
        )
        templates = [
            '{"op":"nope","id":%s}',
            '{"op":"subscribe","topic":"/fuzz/sub","id":"ID","type":"std_msgs/String","throttle_rate":%s}',
            '{"op":"call_service","service":"/rosapi/get_time","id":"ID","timeout":%s}',
        ]
        which = rng.randrange(3)
        frame_id = f"{client}:{i}"
        expect = {"error": ("error", frame_id), "response": ("response", frame_id, True)}.get(
            outcomes[which], outcomes[which]
        )
        return Plan((templates[which] % number).replace("ID", frame_id), expect)

    @maker(2)
    def deep_nesting(i):
        depth = rng.choice([10, 900, 5000, 40_000])
        # without an id: refused for the nesting, the list msg or the unknown topic type, never executed
        return Plan('{"op":"publish","topic":"/fuzz/deep","msg":' + "[" * depth + "]" * depth + "}", ("error", None))

    @maker(2)
    def oversize(i):
        return Plan(
            json.dumps(
                {
                    **valid_publish,
                    "msg": {"data": "z" * (MAX_MESSAGE_SIZE + rng.randint(1, 5000))},
                    "id": f"{client}:{i}",
                }
            ),
            ("error", None),
        )

    @maker(3)
    def binary(i):
        data = bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 64)))
        if rng.random() < 0.3:
            data = json.dumps({**valid_publish, "id": f"{client}:{i}"}).encode()  # JSON in a binary frame
        return Plan(data, ("error", None))

    @maker(2)
    def unicode_names(i):
        name = rng.choice(["/fuzz/\u00e9t\u00e9", "/fuzz/\u4e2d", "/fuzz/\U0001f600", "/fuzz/a b", "/fuzz//x", "~x"])
        return Plan({"op": "subscribe", "topic": name, "type": "std_msgs/String", "id": f"{client}:{i}"}, "maybe-error")

    weights = [w for w, _ in makers]
    plans = [Plan({"op": "advertise", "topic": TOPIC, "type": "std_msgs/String"}, None)]
    i = 0
    while len(plans) < FRAMES_PER_CLIENT:
        i += 1
        made = rng.choices(makers, weights)[0][1](i)
        plans.extend(made if isinstance(made, list) else [made])
    return plans


def is_call_service(frame):
    """Whether a planned frame is a call_service op naming a service (a refused one is also answered with a
    failed service_response, so that client libraries waiting for the reply are not left hanging)."""
    try:
        obj = frame if isinstance(frame, dict) else json.loads(frame)
    except (ValueError, RecursionError):
        return False
    return isinstance(obj, dict) and obj.get("op") == "call_service" and isinstance(obj.get("service"), str)


def encode(frame):
    return frame if isinstance(frame, (str, bytes)) else json.dumps(frame)


async def fuzz_one_client(url, name, plans, deadline):
    """Sends the plans in batches; after each batch, reads until every answer it must bring has come.
    Returns the statistics; raises AssertionError on an unexpected or missing answer."""
    conn = await websocket_connect(url, max_message_size=64 * 1024 * 1024)
    stats = {"frames": 0, "errors": 0, "responses": 0, "maybe_errors": 0}
    for start in range(0, len(plans), BATCH):
        batch = plans[start : start + BATCH]
        errors_with_id, responses, idless, maybe = {}, {}, 0, 0
        for plan in batch:
            await conn.write_message(encode(plan.frame), binary=isinstance(plan.frame, bytes))
            expect = plan.expect
            if expect == "maybe-error":
                maybe += 1
            elif expect and expect[0] == "error" and expect[1] is None:
                idless += 1
            elif expect and expect[0] == "error":
                errors_with_id[expect[1]] = errors_with_id.get(expect[1], 0) + 1
                if is_call_service(plan.frame):
                    responses[expect[1]] = False
            elif expect:
                responses[expect[1]] = expect[2]
        stats["frames"] += len(batch)
        # a marker call: its answer comes after every answer to the batch that is synchronous in the bridge
        marker = f"marker:{start}"
        await conn.write_message(json.dumps({"op": "call_service", "service": "/fuzz/none_marker", "id": marker}))
        responses[marker] = False
        while responses or errors_with_id or idless > 0:
            remaining = deadline - time.monotonic()
            assert remaining > 0, (
                f"batch at {start}: still waiting for responses {sorted(responses)[:5]}, "
                f"errors {sorted(errors_with_id)[:5]}, {idless} id-less errors"
            )
            raw = await asyncio.wait_for(conn.read_message(), remaining)
            assert raw is not None, f"the bridge closed the connection during batch {start}"
            frame = json.loads(raw)
            if frame["op"] == "status":
                assert frame["level"] == "error", frame
                frame_id = frame.get("id")
                if frame_id in errors_with_id:
                    errors_with_id[frame_id] -= 1
                    if not errors_with_id[frame_id]:
                        del errors_with_id[frame_id]
                    stats["errors"] += 1
                elif frame_id is None and idless > 0:
                    idless -= 1
                    stats["errors"] += 1
                elif maybe > 0:
                    maybe -= 1
                    stats["maybe_errors"] += 1
                else:
                    raise AssertionError(f"unexpected error {frame} in batch {start}")
            elif frame["op"] == "service_response":
                assert frame.get("id") in responses, f"unexpected response {frame}"
                assert frame["result"] == responses.pop(frame["id"]), frame
                stats["responses"] += 1
            else:
                assert frame["op"] == "publish" and frame["topic"] == "/fuzz/sub", frame
    # the fuzzed connection still publishes and subscribes: its own messages come back through ROS
    echo = f"/fuzz/echo_{name}"
    for op in ("subscribe", "advertise"):
        await conn.write_message(json.dumps({"op": op, "topic": echo, "type": "std_msgs/String"}))
    while True:
        assert time.monotonic() < deadline, "no echo through ROS on the fuzzed connection"
        await conn.write_message(json.dumps({"op": "publish", "topic": echo, "msg": {"data": "echo"}}))
        try:
            raw = await asyncio.wait_for(conn.read_message(), 0.5)
        except TimeoutError:
            continue
        assert raw is not None, "the bridge closed the fuzzed connection"
        frame = json.loads(raw)
        if frame["op"] == "publish" and frame["topic"] == echo:
            assert frame["msg"] == {"data": "echo"}
            break
        assert frame["op"] == "publish", frame  # nothing else may come
    conn.close()
    return stats


def test_ten_thousand_fuzzed_frames_leave_the_bridge_working(ros, node, fuzz_bridge):
    from std_msgs.msg import String

    proc, port = fuzz_bridge.proc, fuzz_bridge.port
    url = f"ws://127.0.0.1:{port}/"
    bridge = ProcStat(node_pid(ros, "/fuzz_bridge"))
    rss_before = bridge.rss_mb()
    plans = {f"c{seed}": generate(random.Random(seed), f"c{seed}") for seed in (1, 2)}
    started = time.monotonic()

    async def run():
        deadline = time.monotonic() + 120  # a hang fails here; the run itself takes ~20-40 s on 2 loaded cores
        return await asyncio.gather(*(fuzz_one_client(url, name, p, deadline) for name, p in plans.items()))

    loop = asyncio.new_event_loop()  # not asyncio.run: it would leave no current loop for WsClient below
    try:
        stats = loop.run_until_complete(run())
    finally:
        loop.close()
    elapsed = time.monotonic() - started
    rss_after = bridge.rss_mb()
    frames = sum(s["frames"] for s in stats)
    print(f"fuzz: {frames} frames in {elapsed:.1f} s, stats {stats}, bridge RSS {rss_before:.1f} -> {rss_after:.1f} MB")
    assert frames >= 10_000
    assert proc.alive()
    assert sum(s["errors"] for s in stats) > 3_000 and sum(s["responses"] for s in stats) > 1_000
    assert rss_after < rss_before + 150, f"bridge RSS grew from {rss_before:.1f} to {rss_after:.1f} MB"

    # a fresh connection publishes to ROS and receives from ROS
    got = []
    sub = node.Subscriber("/fuzz/after", String, lambda m: got.append(m.data))
    pub = node.Publisher("/fuzz/back", String, queue_size=10)
    client = WsClient(url)
    try:
        client.send({"op": "advertise", "topic": "/fuzz/after", "type": "std_msgs/String"})
        client.send({"op": "subscribe", "topic": "/fuzz/back", "type": "std_msgs/String"})

        def round_trip():
            client.send({"op": "publish", "topic": "/fuzz/after", "msg": {"data": "still here"}})
            pub.publish(String("back to you"))
            try:
                frame = client.recv(timeout=0.5)
            except TimeoutError:
                return False
            return got and frame["op"] == "publish" and frame["msg"] == {"data": "back to you"}

        wait_for(round_trip, 30, interval=0.1, what="a round trip through ROS on a fresh connection")
        assert got[0] == "still here"
    finally:
        client.close()
        sub.unregister()
        pub.unregister()
