"""rosbridge.ros_side.tcpros: the framing and the connection headers, against what rospy and rosgraph do."""

import io
import random

import pytest
from geometry_msgs.msg import Twist
from rospy.impl.tcpros_pubsub import TCPROSHandler
from std_msgs.msg import String

from rosbridge.ros_side import tcpros


def messages_of(sizes, seed=0):
    rnd = random.Random(seed)
    return [bytes(rnd.randrange(256) for _ in range(size)) for size in sizes]


@pytest.mark.parametrize("seed", range(20))
def test_frames_split_anywhere_come_out_whole_and_in_order(seed):
    rnd = random.Random(seed)
    messages = messages_of([rnd.choice((0, 1, 3, 4, 5, 48, 300, 70_000)) for _ in range(30)], seed)
    stream = b"".join(tcpros.frame(m) for m in messages)
    reader, got, offset = tcpros.FrameReader(), [], 0
    while offset < len(stream):
        step = rnd.choice((1, 2, 3, 5, 64, 4096, 100_000))
        got += reader.feed(stream[offset : offset + step])
        offset += step
    assert got == messages
    assert reader.into() is None


def test_a_big_message_is_read_in_place_and_small_ones_around_it_as_usual():
    reader = tcpros.FrameReader()
    big = messages_of([tcpros.BIG_FRAME + 5])[0]
    stream = tcpros.frame(b"before") + tcpros.frame(big) + tcpros.frame(b"after")
    assert reader.feed(stream[:3]) == [] and reader.into() is None  # the length itself is not complete
    assert reader.feed(stream[3:20]) == [b"before"]
    space = reader.into()
    assert len(space) == len(big) - 6  # the 6 bytes of it that came with "before" are in place already
    rest = stream[20 : 20 + len(space)]
    space[:1000] = rest[:1000]
    assert reader.received(1000) == []
    reader.into()[: len(rest) - 1000] = rest[1000:]
    assert reader.received(len(rest) - 1000) == [big]
    assert reader.into() is None
    assert reader.feed(stream[20 + len(rest) :]) == [b"after"]


def test_a_frame_longer_than_the_limit_is_refused_before_its_bytes_come():
    reader = tcpros.FrameReader(max_size=100)
    assert reader.feed(tcpros.frame(b"z" * 100)) == [b"z" * 100]
    with pytest.raises(tcpros.TcprosError, match="101 bytes"):
        reader.feed((101).to_bytes(4, "little"))


def test_the_header_can_be_taken_alone_under_its_own_limit():
    reader = tcpros.FrameReader(max_size=10)
    data = tcpros.frame(b"header") + tcpros.frame(b"m" * 50)  # (a latched message may come with the header)
    assert reader.feed(data, most=1) == [b"header"]
    reader.max_size = 100
    assert reader.feed(b"") == [b"m" * 50]


def test_frame_is_what_a_rospy_subscriber_reads():
    buff = io.BytesIO()
    msg = String(data="hello")
    msg.serialize(buff)
    framed = tcpros.frame(buff.getvalue())
    assert framed[:4] == len(buff.getvalue()).to_bytes(4, "little")
    assert String().deserialize(framed[4:]).data == "hello"


def test_a_numbered_frame_carries_the_seq_in_the_header_wrapping_at_32_bits():
    from std_msgs.msg import Header

    buff = io.BytesIO()
    Header(seq=77, frame_id="f").serialize(buff)
    data = buff.getvalue()
    for seq, expected in ((5, 5), (2**32 + 3, 3)):
        framed = tcpros.frame(data, seq)
        assert framed[:4] == len(data).to_bytes(4, "little")
        header = Header().deserialize(framed[4:])
        assert (header.seq, header.frame_id) == (expected, "f")


def test_headers_survive_the_round_trip_through_rosgraph():
    fields = tcpros.subscriber_header("/cmd_vel", Twist, "/rosbridge")
    encoded = tcpros.encode_header(fields)
    assert tcpros.decode_header(encoded[4:]) == fields
    assert fields["md5sum"] == Twist._md5sum and fields["type"] == "geometry_msgs/Twist"


def test_a_header_too_big_or_malformed_is_refused():
    with pytest.raises(tcpros.TcprosError):
        tcpros.header_size((tcpros.MAX_HEADER + 1).to_bytes(4, "little"))
    with pytest.raises(tcpros.TcprosError):
        tcpros.decode_header(b"\xff\xff\xff\x7fabcd")


def subscriber(**fields):
    header = {"topic": "/cmd_vel", "md5sum": Twist._md5sum, "callerid": "/teleop", "type": "geometry_msgs/Twist"}
    header.update(fields)
    return {k: v for k, v in header.items() if v is not None}


def test_the_reply_to_a_matching_subscriber_describes_the_topic():
    reply = tcpros.publisher_reply(subscriber(), "/cmd_vel", Twist, True, "/rosbridge")
    assert reply == {
        "callerid": "/rosbridge",
        "md5sum": Twist._md5sum,
        "type": "geometry_msgs/Twist",
        "topic": "/cmd_vel",
        "message_definition": Twist._full_text,
        "latching": "1",
    }
    assert tcpros.publisher_reply(subscriber(md5sum="*", type="*"), "/cmd_vel", Twist, False, "/b")["latching"] == "0"


@pytest.mark.parametrize(
    "fields",
    [
        {"md5sum": "0" * 32},
        {"md5sum": "0" * 32, "type": "std_msgs/String"},
        {"md5sum": "0" * 32, "type": None},
        {"topic": None},
        {"md5sum": None},
        {"callerid": None},
    ],
)
def test_refusals_are_rospys(fields, monkeypatch):
    """The same error text a rospy publisher gives (rostopic and roscpp show it to the user)."""
    ours = tcpros.publisher_reply(subscriber(**fields), "/cmd_vel", Twist, False, "/rosbridge")

    class Topic:
        data_class, closed, is_latch, headers = Twist, False, False, None

    class Manager:
        @staticmethod
        def get_publisher_impl(name):
            return Topic

    monkeypatch.setattr("rospy.impl.registration.get_topic_manager", lambda: Manager)
    monkeypatch.setattr("rospy.core.is_shutdown_requested", lambda: False)
    theirs = TCPROSHandler().topic_connection_handler(None, None, subscriber(**fields))
    assert ours == {"error": theirs}


def test_nodelay_as_the_subscriber_asks():
    assert tcpros.wants_nodelay({"tcp_nodelay": "1"}) and not tcpros.wants_nodelay({"tcp_nodelay": "0"})
    assert not tcpros.wants_nodelay({})
