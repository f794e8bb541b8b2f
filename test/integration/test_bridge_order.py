"""A client's operations take effect in the order it sent them, as in the reference: what an advertise,
advertise_service or subscribe does on the ROS side (off the event loop) is done before the client's next
request is handled, so a request sent right after it sees its effect."""

import json

import pytest

from bridge_client import RawWebSocket
from fixtures import bridge_fixture

bridge = bridge_fixture("order_bridge")


def send_at_once(port, *requests):
    """Sends the requests in one write, as a client library does when they are queued together."""
    client = RawWebSocket(port)
    client.sock.sendall(b"".join(RawWebSocket.frame(json.dumps(r).encode()) for r in requests))
    return client


def replies(client, count):
    return [json.loads(client.recv_frame()[1]) for _ in range(count)]


@pytest.mark.parametrize("attempt", range(3))
def test_a_service_advertised_then_called_at_once_answers(bridge, attempt):
    service = f"/order/adder_{attempt}"
    client = send_at_once(
        bridge,
        {"op": "advertise_service", "service": service, "type": "std_srvs/Trigger"},
        {"op": "call_service", "service": service, "id": "call"},
    )
    try:
        forwarded = json.loads(client.recv_frame()[1])  # the bridge forwards the call to us, the provider
        assert forwarded["op"] == "call_service" and forwarded["service"] == service, forwarded
        client.sock.sendall(
            RawWebSocket.frame(
                json.dumps(
                    {
                        "op": "service_response",
                        "service": service,
                        "id": forwarded["id"],
                        "result": True,
                        "values": {"success": True, "message": "added"},
                    }
                ).encode()
            )
        )
        answer = json.loads(client.recv_frame()[1])
        assert answer["op"] == "service_response" and answer["id"] == "call", answer
        assert answer["result"] is True and answer["values"]["message"] == "added", answer
    finally:
        client.close()


@pytest.mark.parametrize("attempt", range(3))
def test_a_topic_advertised_then_listed_at_once_is_in_the_list(bridge, attempt):
    topic = f"/order/listed_{attempt}"
    client = send_at_once(
        bridge,
        {"op": "advertise", "topic": topic, "type": "std_msgs/String"},
        {"op": "call_service", "service": "/rosapi/topics", "id": "list"},
    )
    try:
        (answer,) = replies(client, 1)
        assert answer["id"] == "list" and topic in answer["values"]["topics"], answer
    finally:
        client.close()


def test_a_subscription_then_a_topic_type_query_sees_the_subscriber(bridge, ros):
    topic = "/order/subscribed"
    client = send_at_once(
        bridge,
        {"op": "subscribe", "topic": topic, "type": "std_msgs/Int32"},
        {"op": "call_service", "service": "/rosapi/subscribers", "args": {"topic": topic}, "id": "who"},
    )
    try:
        (answer,) = replies(client, 1)
        assert answer["values"]["subscribers"] == ["/order_bridge"], answer
    finally:
        client.close()


def test_advertise_publish_unadvertise_advertise_again(ws, node):
    from std_msgs.msg import String

    topic = "/order/again"
    got = []
    node.Subscriber(topic, String, lambda msg: got.append(msg.data))
    ws.send({"op": "advertise", "topic": topic, "type": "std_msgs/String"})
    ws.send({"op": "publish", "topic": topic, "msg": {"data": "one"}})
    ws.send({"op": "unadvertise", "topic": topic})
    ws.send({"op": "advertise", "topic": topic, "type": "std_msgs/String", "id": "again"})
    for n in range(50):
        ws.send({"op": "publish", "topic": topic, "msg": {"data": f"two {n}"}})
    reply = ws.request({"op": "set_level", "level": "bogus", "id": "end"})
    assert reply["id"] == "end", reply  # nothing was refused on the way
    import time

    deadline = time.monotonic() + 10
    while not any(text.startswith("two") for text in got) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert any(text.startswith("two") for text in got), got
