"""The protocol over a real socket, frame by frame: every op and option, and every kind of bad input (each
answered with a status error while the connection keeps working)."""

import base64
import io
import json
import threading
import time

import cbor2
import pytest
from PIL import Image

from bridge_client import WsClient, ping
from fixtures import bridge_fixture
from harness import wait_for

MAX_MESSAGE_SIZE = 100_000

bridge = bridge_fixture("protocol_bridge", max_message_size=MAX_MESSAGE_SIZE)


class Publisher:
    """A rospy publisher that repeats one message every 50 ms while the test needs it."""

    def __init__(self, node, topic, cls, msg):
        self.pub = node.Publisher(topic, cls, queue_size=10)
        self.msg, self.stop = msg, threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.wait(0.05):
            self.pub.publish(self.msg)

    def close(self):
        self.stop.set()
        self.thread.join()
        self.pub.unregister()


def binary_frame(ws):
    """The next binary frame (text frames before it are skipped)."""
    frame = ws.recv_raw()
    while not isinstance(frame, bytes):
        frame = ws.recv_raw()
    return frame


@pytest.mark.parametrize(
    "frame, expected",
    [
        ("this is not json", "not valid JSON"),
        ('junk {"op": "set_level", "level": "info"}', "not valid JSON"),
        ("42", "JSON object"),
        ('"op"', "JSON object"),
        ("[1, 2]", "JSON object"),
        ('{"op": [1]}', "'op' must be a string"),
        ("{}", "missing field 'op'"),
        ('{"op": "teleport_me", "id": "x"}', "unknown op 'teleport_me'"),
        ('{"op": "status", "level": "error", "msg": "hi"}', "unknown op 'status'"),
        ('{"op": "subscribe", "id": "x"}', "missing required field 'topic'"),
        ('{"op": "subscribe", "topic": 5, "id": "x"}', "'topic' must be a string"),
        (
            '{"op": "subscribe", "topic": "/a", "type": "std_msgs/String", "colour": "red", "id": "x"}',
            "unknown field 'colour'",
        ),
        ('{"op": "subscribe", "topic": "/a", "type": "no_such_pkg/Nope", "id": "x"}', "no_such_pkg/Nope"),
        ('{"op": "subscribe", "topic": "/a", "type": "../../etc", "id": "x"}', "invalid message type"),
        (
            '{"op": "subscribe", "topic": "/a", "type": "std_msgs/String", "compression": "zip", "id": "x"}',
            "compression must be one of",
        ),
        (
            '{"op": "subscribe", "topic": "/a", "type": "std_msgs/String", "throttle_rate": true, "id": "x"}',
            "'throttle_rate' must be a number",
        ),
        ('{"op": "subscribe", "topic": "/bridge_test/never_published", "id": "x"}', "cannot infer"),
        ('{"op": "advertise", "topic": "/a", "type": "std_msgs/NoSuchType", "id": "x"}', "std_msgs/NoSuchType"),
        # names that resolve to something in a message package that is not a message class
        ('{"op": "advertise", "topic": "/a", "type": "std_msgs/sys", "id": "x"}', "unknown message type"),
        ('{"op": "advertise", "topic": "/a", "type": "std_msgs/genpy", "id": "x"}', "unknown message type"),
        ('{"op": "subscribe", "topic": "/a", "type": "std_msgs/struct", "id": "x"}', "unknown message type"),
        ('{"op": "advertise", "topic": "/a", "type": "rospy/AnyMsg", "id": "x"}', "unknown message type"),
        ('{"op": "advertise_service", "service": "/a", "type": "std_srvs/sys", "id": "x"}', "unknown service type"),
        ('{"op": "publish", "topic": "/bridge_test/typeless", "msg": {}, "id": "x"}', "cannot infer"),
        ('{"op": "publish", "topic": "/a", "msg": [1], "id": "x"}', "'msg' must be an object"),
        ('{"op": "call_service", "service": "/a", "args": 3, "id": "x"}', "'args' must be an object or a list"),
        ('{"op": "call_service", "service": "/a", "timeout": -1, "id": "x"}', "timeout must be positive"),
        ('{"op": "unadvertise", "topic": "/never_advertised", "id": "x"}', "not advertised by this client"),
        ('{"op": "unadvertise_service", "service": "/never", "id": "x"}', "not advertised by this client"),
        ('{"op": "service_response", "service": "/never", "result": true, "id": "x"}', "not advertised"),
        ('{"op": "set_level", "level": "loud", "id": "x"}', "level must be one of"),
        ('{"op": "fragment", "id": "f", "data": "x", "num": 3, "total": 2}', "out of range"),
        ('{"op": "png", "data": "not base64 png!", "id": "x"}', "png: cannot read"),
    ],
)
def test_bad_input_gets_an_error_and_the_connection_goes_on(ws, frame, expected):
    ws.send(frame)
    reply = ws.recv()
    assert reply["op"] == "status" and reply["level"] == "error", reply
    assert expected in reply["msg"], reply
    if '"call_service"' in frame:  # and a failed service_response, which client libraries wait for
        response = ws.recv()
        assert response["op"] == "service_response" and response["result"] is False, response
        assert response["values"] == reply["msg"] and response["id"] == reply["id"]
    sent = json.loads(frame) if frame.startswith("{") else None
    if isinstance(sent, dict) and "id" in sent and not isinstance(sent["id"], (dict, list)):
        assert reply.get("id") == sent["id"]
    assert ping(ws)


@pytest.mark.parametrize("request_id", ["\\ud800", "a\\udfff", "\\\\\\ud800"])
def test_a_lone_surrogate_echoed_back_does_not_silence_the_client(ws, request_id):
    """JSON may escape half of a surrogate pair alone; echoed in a status, it must not stop the client's output."""
    ws.send('{"op": "set_level", "level": "x", "id": "%s"}' % request_id)
    reply = ws.recv()
    assert reply["op"] == "status" and reply["id"] == json.loads('"%s"' % request_id), reply
    assert ping(ws)


def test_bad_field_in_a_message_is_named(ws):
    ws.send({"op": "advertise", "topic": "/bridge_test/bad_twist", "type": "geometry_msgs/Twist"})
    reply = ws.request(
        {"op": "publish", "topic": "/bridge_test/bad_twist", "id": "p1", "msg": {"linear": {"x": "fast"}}}
    )
    assert reply["level"] == "error" and "linear.x" in reply["msg"]
    reply = ws.request({"op": "publish", "topic": "/bridge_test/bad_twist", "id": "p2", "msg": {"linear": {"w": 1}}})
    assert "'w'" in reply["msg"]
    assert ping(ws)


def test_binary_frame_is_refused(ws):
    ws.send(json.dumps({"op": "set_level", "level": "info"}).encode())
    reply = ws.recv()
    assert reply["op"] == "status" and reply["level"] == "error" and "binary frame" in reply["msg"]
    assert ping(ws)


def test_over_size_frame_is_refused_and_the_connection_kept(ws):
    ws.send(json.dumps({"op": "publish", "topic": "/x", "msg": {"data": "x" * (2 * MAX_MESSAGE_SIZE)}}))
    reply = ws.recv()
    assert reply["level"] == "error" and "max_message_size" in reply["msg"]
    assert ping(ws)


def test_other_clients_are_unaffected_by_bad_input(bridge, ws):
    other = WsClient(f"ws://127.0.0.1:{bridge}/")
    try:
        for frame in ("42", "{", '{"op": [1]}', b"\x00\x01"):
            ws.send(frame)
        assert ping(other)
    finally:
        other.close()


def test_fragments_in_are_reassembled(ws, node):
    from std_msgs.msg import String

    got = []
    sub = node.Subscriber("/bridge_test/fragmented", String, lambda m: got.append(m.data))
    ws.send({"op": "advertise", "topic": "/bridge_test/fragmented", "type": "std_msgs/String"})
    wait_for(lambda: sub.get_num_connections(), 20, what="the subscriber to connect")
    text = json.dumps({"op": "publish", "topic": "/bridge_test/fragmented", "msg": {"data": "piece by piece"}})
    parts = [text[i : i + 10] for i in range(0, len(text), 10)]
    for num in reversed(range(len(parts))):  # any order
        ws.send({"op": "fragment", "id": "frag-1", "data": parts[num], "num": num, "total": len(parts)})
    wait_for(lambda: got, 20, what="the reassembled message")
    assert got == ["piece by piece"]
    sub.unregister()


def test_fragments_out_and_png_subscriptions(ws, node):
    from std_msgs.msg import Float64MultiArray

    values = [0.5, -1.25, 3.0, 1e10]
    pub = Publisher(node, "/bridge_test/array", Float64MultiArray, Float64MultiArray(data=values))
    try:
        ws.send(
            {
                "op": "subscribe",
                "id": "frag",
                "topic": "/bridge_test/array",
                "type": "std_msgs/Float64MultiArray",
                "fragment_size": 20,
            }
        )
        first = ws.recv_op("fragment")
        parts = {first["num"]: first["data"]}
        while len(parts) < first["total"]:
            part = ws.recv_op("fragment", id=first["id"])
            parts[part["num"]] = part["data"]
        message = json.loads("".join(parts[i] for i in range(first["total"])))
        assert message["op"] == "publish" and message["msg"]["data"] == values
        ws.send({"op": "unsubscribe", "topic": "/bridge_test/array"})

        ws.send({"op": "subscribe", "topic": "/bridge_test/array", "compression": "png"})
        png = ws.recv_op("png")
        with Image.open(io.BytesIO(base64.b64decode(png["data"]))) as image:
            text = image.convert("RGB").tobytes().decode().rstrip("\n")
        assert json.loads(text)["msg"]["data"] == values
    finally:
        pub.close()


def test_cbor_and_cbor_raw_are_binary_frames(ws, node):
    from std_msgs.msg import Float64MultiArray

    values = [0.5, -1.25, 3.0]
    pub = Publisher(node, "/bridge_test/cbor", Float64MultiArray, Float64MultiArray(data=values))
    try:
        ws.send(
            {
                "op": "subscribe",
                "topic": "/bridge_test/cbor",
                "type": "std_msgs/Float64MultiArray",
                "compression": "cbor",
            }
        )
        decoded = cbor2.loads(binary_frame(ws))
        assert decoded["op"] == "publish" and decoded["topic"] == "/bridge_test/cbor"
        data = decoded["msg"]["data"]  # a float64 typed array (RFC 8746 tag 86)
        assert isinstance(data, cbor2.CBORTag) and data.tag == 86
        ws.send({"op": "unsubscribe", "topic": "/bridge_test/cbor"})

        ws.send({"op": "subscribe", "topic": "/bridge_test/cbor", "compression": "cbor-raw"})
        raw = cbor2.loads(binary_frame(ws))["msg"]
        assert set(raw) == {"bytes", "secs", "nsecs"} and raw["secs"] > 0
        msg = Float64MultiArray()
        msg.deserialize(raw["bytes"])
        assert list(msg.data) == values
    finally:
        pub.close()


def test_a_camera_image_arrives_whole_as_json_cbor_and_fragments(ws, node):
    # big enough that its data goes to the socket as a part of its own (frames.SplicedFrame)
    from sensor_msgs.msg import Image as RosImage

    data = bytes(range(256)) * 3600
    image = RosImage(height=480, width=640, encoding="rgb8", step=1920, data=data)
    image.header.frame_id = "cam\u00e9ra"
    expected = {"height": 480, "width": 640, "encoding": "rgb8", "is_bigendian": 0, "step": 1920}
    pub = Publisher(node, "/bridge_test/camera", RosImage, image)
    try:
        for options in ({}, {"compression": "cbor"}, {"fragment_size": 400_000}):
            ws.send({"op": "subscribe", "topic": "/bridge_test/camera", "type": "sensor_msgs/Image", **options})
            if "fragment_size" in options:
                parts = [ws.recv_op("fragment", num=num) for num in range(4)]
                assert {p["total"] for p in parts} == {4} and len({p["id"] for p in parts}) == 1
                frame = json.loads("".join(p["data"] for p in parts))
            elif options:
                frame = cbor2.loads(binary_frame(ws))
            else:
                frame = ws.recv_op("publish", topic="/bridge_test/camera")
            ws.send({"op": "unsubscribe", "topic": "/bridge_test/camera"})
            msg = frame["msg"]
            got = msg.pop("data")
            assert (got if options.get("compression") else base64.b64decode(got, validate=True)) == data, options
            assert msg.pop("header")["frame_id"] == "cam\u00e9ra"
            assert msg == expected, options
            ping(ws)  # nothing else pending: the next subscription's first frame is its own
    finally:
        pub.close()


def test_call_service_with_positional_args_and_timeout(ws, node):
    from std_srvs.srv import SetBool, SetBoolResponse

    slow = threading.Event()

    def handle(req):
        if slow.is_set():
            time.sleep(3)  # longer than the call's timeout below
        return SetBoolResponse(req.data, "done")

    server = node.Service("/bridge_test/positional", SetBool, handle)
    try:
        reply = ws.request({"op": "call_service", "id": "c1", "service": "/bridge_test/positional", "args": [True]})
        assert reply == {
            "op": "service_response",
            "service": "/bridge_test/positional",
            "id": "c1",
            "result": True,
            "values": {"success": True, "message": "done"},
        }
        reply = ws.request(
            {"op": "call_service", "id": "c2", "service": "/bridge_test/positional", "args": [True, False]}
        )
        assert reply["result"] is False and "positional" in reply["values"]
        slow.set()
        reply = ws.request(
            {
                "op": "call_service",
                "id": "c3",
                "service": "/bridge_test/positional",
                "args": {"data": False},
                "timeout": 0.5,
            }
        )
        assert reply["result"] is False and "timed out" in reply["values"]
        reply = ws.request(
            {
                "op": "call_service",
                "id": "c4",
                "service": "/bridge_test/positional",
                "type": "std_srvs/SetBool",
                "args": {},
            }
        )
        assert reply["result"] is True and reply["values"]["success"] is False
    finally:
        server.shutdown()


def test_status_levels(ws):
    ws.send({"op": "set_level", "level": "warning"})
    reply = ws.request({"op": "unsubscribe", "topic": "/not_subscribed", "id": "u1"})
    assert reply["level"] == "warning" and "not subscribed" in reply["msg"]
    ws.send({"op": "set_level", "level": "none"})
    ws.send("not json")
    ws.send({"op": "set_level", "level": "error"})
    ws.send({"op": "unsubscribe", "topic": "/x", "id": "u2", "extra": 1})
    reply = ws.recv()  # the next frame: nothing came back for "not json" at level none
    assert reply["id"] == "u2" and reply["level"] == "error" and "extra" in reply["msg"]


def test_subscribe_merging_and_unsubscribe_by_id(ws, node):
    from std_msgs.msg import Int32

    pub = Publisher(node, "/bridge_test/merge", Int32, Int32(7))
    try:
        ws.send({"op": "subscribe", "id": "a", "topic": "/bridge_test/merge", "type": "std_msgs/Int32"})
        ws.send(
            {"op": "subscribe", "id": "b", "topic": "/bridge_test/merge", "type": "std_msgs/Int32", "fragment_size": 10}
        )
        assert ws.recv_op("fragment")["id"]  # merged: the lowest fragment_size wins
        ws.send({"op": "unsubscribe", "id": "b", "topic": "/bridge_test/merge"})
        ws.recv_until(lambda f: f.get("op") == "publish" and f["msg"] == {"data": 7})
        ws.send({"op": "unsubscribe", "id": "a", "topic": "/bridge_test/merge"})
        ws.send({"op": "set_level", "level": "warning"})
        reply = ws.request({"op": "unsubscribe", "id": "a", "topic": "/bridge_test/merge"})
        assert "not subscribed" in reply["msg"]
    finally:
        pub.close()


def test_throttled_stream_ends_on_the_last_value(ws, node):
    from std_msgs.msg import Int32

    pub = node.Publisher("/bridge_test/throttled", Int32, queue_size=100)
    ws.send({"op": "subscribe", "topic": "/bridge_test/throttled", "type": "std_msgs/Int32", "throttle_rate": 1000})
    wait_for(lambda: pub.get_num_connections(), 20, what="the bridge to subscribe")
    for n in range(20):
        pub.publish(Int32(n))
    got = []
    while not got or got[-1] != 19:
        got.append(ws.recv_op("publish", timeout=10)["msg"]["data"])
    assert len(got) <= 3 and got == sorted(got)
    pub.unregister()


def test_client_service_gets_calls_and_bad_responses_are_refused(ws, ros):
    ws.send({"op": "advertise_service", "service": "/bridge_test/client_srv", "type": "std_srvs/SetBool"})
    wait_for(lambda: "/bridge_test/client_srv" in ros.run(["rosservice", "list"]).stdout, 20, what="service")
    caller = ros.spawn(["rosservice", "call", "/bridge_test/client_srv", "data: true"], "caller")
    call = ws.recv_op("call_service")
    assert call["service"] == "/bridge_test/client_srv" and call["args"] == {"data": True}
    reply = ws.request(
        {
            "op": "service_response",
            "service": "/bridge_test/client_srv",
            "id": call["id"],
            "result": True,
            "values": {"success": "very"},
        }
    )
    assert reply["level"] == "error" and "success" in reply["msg"]
    caller.popen.wait(20)
    assert caller.popen.returncode != 0 and "success" in caller.output()

    caller = ros.spawn(["rosservice", "call", "/bridge_test/client_srv", "data: false"], "caller")
    call = ws.recv_op("call_service")
    ws.send(
        {
            "op": "service_response",
            "service": "/bridge_test/client_srv",
            "id": call["id"],
            "result": True,
            "values": {"success": True, "message": "fine"},
        }
    )
    caller.popen.wait(20)
    assert caller.popen.returncode == 0 and "fine" in caller.output()
    ws.send({"op": "unadvertise_service", "service": "/bridge_test/client_srv"})
    wait_for(lambda: "/bridge_test/client_srv" not in ros.run(["rosservice", "list"]).stdout, 20, what="service gone")


def test_result_false_answers_object_values_with_a_warning_and_fails_with_a_text(ws, ros):
    ws.send({"op": "set_level", "level": "warning"})  # (errors only by default)
    ws.send({"op": "advertise_service", "service": "/bridge_test/false_srv", "type": "std_srvs/SetBool"})
    wait_for(lambda: "/bridge_test/false_srv" in ros.run(["rosservice", "list"]).stdout, 20, what="service")
    caller = ros.spawn(["rosservice", "call", "/bridge_test/false_srv", "data: true"], "caller")
    call = ws.recv_op("call_service")
    warning = ws.request(
        {
            "op": "service_response",
            "service": "/bridge_test/false_srv",
            "id": call["id"],
            "result": False,
            "values": {"success": True, "message": "answered anyway"},
        }
    )
    assert warning["level"] == "warning" and "result" in warning["msg"]
    caller.popen.wait(20)
    assert caller.popen.returncode == 0 and "answered anyway" in caller.output()

    caller = ros.spawn(["rosservice", "call", "/bridge_test/false_srv", "data: true"], "caller")
    call = ws.recv_op("call_service")
    ws.send(
        {
            "op": "service_response",
            "service": "/bridge_test/false_srv",
            "id": call["id"],
            "result": False,
            "values": "the motor is off",
        }
    )
    caller.popen.wait(20)
    assert caller.popen.returncode != 0 and "the motor is off" in caller.output()
    ws.send({"op": "unadvertise_service", "service": "/bridge_test/false_srv"})


def test_leaving_client_fails_the_pending_ros_call(bridge, ros):
    ws = WsClient(f"ws://127.0.0.1:{bridge}/")
    ws.send({"op": "advertise_service", "service": "/bridge_test/leaver", "type": "std_srvs/Trigger"})
    wait_for(lambda: "/bridge_test/leaver" in ros.run(["rosservice", "list"]).stdout, 20, what="service")
    caller = ros.spawn(["rosservice", "call", "/bridge_test/leaver"], "caller")
    ws.recv_op("call_service")
    ws.abort()
    caller.popen.wait(20)
    assert caller.popen.returncode != 0 and "disconnected" in caller.output()
    wait_for(lambda: "/bridge_test/leaver" not in ros.run(["rosservice", "list"]).stdout, 20, what="gone")
