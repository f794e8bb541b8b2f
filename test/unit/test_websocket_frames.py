"""rosbridge.transport.rfc6455 without sockets: a client's bytes in any pieces, every frame kind, every way of
breaking RFC 6455, permessage-deflate both ways (and a big frame deflated once for every client that sends it
compressed); and the budget's turns over a reader fed a flood."""

import base64
import os
import random
import struct
import tracemalloc
import zlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rosbridge.transport import rfc6455 as ws
from rosbridge.transport.budget import FRAMES_PER_TURN, ClientBudget


def client_frame(payload, opcode=ws.TEXT, fin=True, rsv1=False, masked=True, length=None):
    """A frame as a client sends it (masked with a random key)."""
    length = len(payload) if length is None else length
    first = (0x80 if fin else 0) | (0x40 if rsv1 else 0) | opcode
    if length < 126:
        head = struct.pack("!BB", first, (0x80 if masked else 0) | length)
    elif length < 1 << 16:
        head = struct.pack("!BBH", first, (0x80 if masked else 0) | 126, length)
    else:
        head = struct.pack("!BBQ", first, (0x80 if masked else 0) | 127, length)
    if not masked:
        return head + payload
    key = os.urandom(4)
    return head + key + ws.xor_mask(key, payload)


def events(reader):
    out = []
    while (event := reader.next_event()) is not None:
        out.append(event)
    return out


def test_handshake_answer_is_rfc_6455s_example():
    assert ws.accept_key("dGhlIHNhbXBsZSBub25jZQ==") == "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="


@pytest.mark.parametrize(
    "headers, status",
    [
        (
            {"Connection": "Upgrade", "Sec-WebSocket-Version": "13", "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="},
            None,
        ),
        (
            {
                "Connection": "keep-alive, Upgrade",
                "Sec-WebSocket-Version": "13",
                "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==",
            },
            None,
        ),
        (
            {
                "Connection": "keep-alive",
                "Sec-WebSocket-Version": "13",
                "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==",
            },
            400,
        ),
        ({"Connection": "Upgrade", "Sec-WebSocket-Version": "8", "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="}, 426),
        ({"Connection": "Upgrade", "Sec-WebSocket-Version": "13", "Sec-WebSocket-Key": "short"}, 400),
        ({"Connection": "Upgrade", "Sec-WebSocket-Version": "13"}, 400),
    ],
)
def test_handshake_errors(headers, status):
    error = ws.handshake_error(headers)
    assert (error[0] if error else None) == status


def test_frames_in_any_pieces_come_out_whole_and_in_order():
    big = os.urandom(200_000)
    data = b"".join(
        [
            client_frame(b'{"op":"a"}'),
            client_frame(big, ws.BINARY),
            client_frame(b"one ", fin=False),
            client_frame(b"are you there", ws.PING),
            client_frame(b"two ", ws.CONTINUATION, fin=False),
            client_frame("trois é".encode(), ws.CONTINUATION),
            client_frame(b"", ws.PONG),
            client_frame(struct.pack("!H", 1000) + b"bye", ws.CLOSE),
        ]
    )
    for size in (1, 2, 3, 7, 1000, 65536, len(data)):
        reader = ws.FrameReader(1 << 20)
        got = []
        for at in range(0, len(data), size):
            reader.receive(data[at : at + size])
            got += events(reader)
        assert [(kind, payload) for kind, payload, _ in got] == [
            (ws.TEXT, '{"op":"a"}'),
            (ws.BINARY, big),
            (ws.PART, None),
            (ws.PING, b"are you there"),
            (ws.PART, None),
            (ws.TEXT, "one two trois é"),
            (ws.PONG, b""),
            (ws.CLOSE, (1000, "bye")),
        ]
        assert [size for _, _, size in got] == [10, 200_000, 4, 13, 4, 8, 0, 5]
        assert reader.buffered == 0


@pytest.mark.parametrize(
    "frame, code",
    [
        (client_frame(b"x", masked=False), ws.PROTOCOL_ERROR),
        (client_frame(b"x", rsv1=True), ws.PROTOCOL_ERROR),  # no extension negotiated
        (client_frame(b"x", opcode=0x3), ws.PROTOCOL_ERROR),
        (client_frame(b"x", opcode=0xB), ws.PROTOCOL_ERROR),
        (client_frame(b"x" * 126, ws.PING), ws.PROTOCOL_ERROR),
        (client_frame(b"x", ws.PING, fin=False), ws.PROTOCOL_ERROR),
        (client_frame(b"x", ws.CONTINUATION), ws.PROTOCOL_ERROR),
        (client_frame(b"a", fin=False) + client_frame(b"b"), ws.PROTOCOL_ERROR),
        (client_frame(b"\xff\xfe"), ws.INVALID_DATA),
        (client_frame(b"\x03", ws.CLOSE), ws.PROTOCOL_ERROR),
        (client_frame(struct.pack("!H", 999), ws.CLOSE), ws.PROTOCOL_ERROR),
        (client_frame(struct.pack("!H", 1005), ws.CLOSE), ws.PROTOCOL_ERROR),
        (client_frame(struct.pack("!H", 1000) + b"\xff", ws.CLOSE), ws.INVALID_DATA),
    ],
    ids=[
        "unmasked",
        "rsv1 without an extension",
        "opcode 3",
        "opcode 11",
        "long ping",
        "fragmented ping",
        "lone continuation",
        "a new message inside one",
        "bad UTF-8",
        "1-byte close",
        "close code 999",
        "close code 1005",
        "close reason bad UTF-8",
    ],
)  # (named: the frames' masks are random, and pytest-xdist's
# workers must collect the same test ids)
def test_what_breaks_the_protocol_is_refused_with_its_close_code(frame, code):
    reader = ws.FrameReader(1000)
    reader.receive(frame)
    with pytest.raises(ws.ProtocolError) as refused:
        events(reader)
    assert refused.value.code == code


def test_a_message_over_the_limit_is_refused_before_its_payload_comes():
    reader = ws.FrameReader(1000)
    reader.receive(client_frame(b"", length=1001)[:4])  # the header only
    with pytest.raises(ws.ProtocolError) as refused:
        reader.next_event()
    assert refused.value.code == ws.TOO_BIG
    reader = ws.FrameReader(1000)  # and in parts
    reader.receive(client_frame(b"x" * 600, fin=False) + client_frame(b"x" * 600, ws.CONTINUATION)[:4])
    assert reader.next_event()[0] == ws.PART
    with pytest.raises(ws.ProtocolError):
        reader.next_event()


def test_an_empty_close_has_no_status():
    reader = ws.FrameReader(100)
    reader.receive(client_frame(b"", ws.CLOSE))
    assert reader.next_event() == (ws.CLOSE, (ws.NO_STATUS, ""), 0)


@given(st.binary(max_size=300), st.binary(min_size=4, max_size=4))
def test_the_pure_and_the_fast_unmasking_agree(data, key):
    from rosbridge.borrowed import websocket_mask

    assert ws.xor_mask(key, memoryview(data)) == websocket_mask(key, memoryview(data))
    assert ws.xor_mask(key, ws.xor_mask(key, data)) == data


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.tuples(st.sampled_from(["text", "binary", "ping"]), st.binary(max_size=300)), max_size=20),
    st.lists(st.integers(1, 50), min_size=1, max_size=10),
)
def test_any_sequence_of_frames_in_any_cuts_reads_back(messages, cuts):
    frames, expected = [], []
    for kind, payload in messages:
        if kind == "text":
            text = payload.decode("latin-1")
            frames.append(client_frame(text.encode()))
            expected.append((ws.TEXT, text))
        elif kind == "binary":
            frames.append(client_frame(payload, ws.BINARY))
            expected.append((ws.BINARY, payload))
        else:
            frames.append(client_frame(payload[:125], ws.PING))
            expected.append((ws.PING, payload[:125]))
    data, reader, got, at, index = b"".join(frames), ws.FrameReader(1 << 16), [], 0, 0
    while at < len(data):
        size = cuts[index % len(cuts)]
        reader.receive(data[at : at + size])
        got += [(kind, payload) for kind, payload, _ in events(reader)]
        at, index = at + size, index + 1
    assert got == expected


# ---- permessage-deflate ------------------------------------------------------------------------------
BOTH = "permessage-deflate; server_no_context_takeover; client_no_context_takeover"


@pytest.mark.parametrize(
    "offer, answer, bits",
    [
        ("permessage-deflate; client_max_window_bits", BOTH, 15),  # Chromium's and Tornado's offer
        ("permessage-deflate", BOTH, 15),  # (client_no_context_takeover added: RFC 7692 7.1.1.2)
        ("x-webkit-deflate-frame, permessage-deflate; client_no_context_takeover", BOTH, 15),
        ("permessage-deflate; server_max_window_bits=10", BOTH + "; server_max_window_bits=10", 10),
        ("permessage-deflate; client_max_window_bits=8", BOTH, 15),  # (we inflate any window)
        ("permessage-deflate; server_max_window_bits=8, permessage-deflate", BOTH, 15),  # the second offer taken
        ("permessage-deflate; server_max_window_bits=8", None, None),  # zlib cannot write that window
        ("permessage-deflate; server_max_window_bits", None, None),  # it needs a value
        ("permessage-deflate; client_max_window_bits=7", None, None),
        ("permessage-deflate; server_no_context_takeover; server_no_context_takeover", None, None),
        ("permessage-deflate; mystery", None, None),
        ("", None, None),
    ],
)
def test_deflate_negotiation(offer, answer, bits):
    assert ws.negotiate_deflate(offer) == (answer, bits)


def client_deflated(payload, compressor=None):
    """A client's compressed message: with no context kept between messages (client_no_context_takeover), each
    with a compressor of its own."""
    compressor = compressor or zlib.compressobj(9, zlib.DEFLATED, -15)
    data = compressor.compress(payload) + compressor.flush(zlib.Z_SYNC_FLUSH)
    assert data.endswith(b"\x00\x00\xff\xff")
    return data[:-4]


def test_deflated_messages_are_unpacked_and_weighed_as_unpacked():
    text = b'{"op":"publish","topic":"/a","msg":{"data":"' + b"a" * 50_000 + b'"}}'
    reader = ws.FrameReader(1 << 20, deflate=True)
    first, second = client_deflated(text), client_deflated(text)
    reader.receive(
        client_frame(first, rsv1=True)
        + client_frame(second[:5], fin=False, rsv1=True)
        + client_frame(second[5:], ws.CONTINUATION)
        + client_frame(b"plain")
    )
    got = events(reader)
    assert [(kind, payload) for kind, payload, _ in got] == [
        (ws.TEXT, text.decode()),
        (ws.PART, None),
        (ws.TEXT, text.decode()),
        (ws.TEXT, "plain"),
    ]
    # (each event weighs what it unpacked, or the compressed bytes it took if more)
    assert got[0][2] == len(text) and len(text) <= got[1][2] + got[2][2] <= len(text) + len(second) + 4


def test_a_client_that_keeps_its_context_after_agreeing_not_to_is_still_understood():
    """Tornado 6.2's client drops the answer's client_no_context_takeover (its header parser loses parameters
    without a value) and points back into its earlier messages."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    texts = [
        b'{"op":"publish","topic":"/a","msg":{"data":"' + os.urandom(n).hex().encode() + b'"}}'
        for n in (3000, 40_000, 10)
    ]
    texts.append(texts[0])  # its window is 32 kB: this one points back past the 80 kB of the second
    reader = ws.FrameReader(1 << 20, deflate=True)
    for text in texts:
        reader.receive(client_frame(client_deflated(text, compressor), rsv1=True))
        assert events(reader)[-1][1] == text.decode()
    assert len(reader._inflated) <= 2 * ws.CONTEXT_BYTES


def test_readers_keep_no_inflater_between_messages():
    """Clients that once sent a compressed message hold no zlib state (about 40 kB each if kept), only the end
    of what they sent."""
    message = client_frame(client_deflated(b'{"op":"set_level","level":"warning"}' * 30), rsv1=True)  # 1 kB
    readers = [ws.FrameReader(1 << 20, deflate=True) for _ in range(200)]
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for reader in readers:
            reader.receive(message)
            assert reader.next_event()[0] == ws.TEXT
        held = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert held < 200 * 4_000, held


@settings(max_examples=60, deadline=None)
@given(
    st.booleans(),
    st.lists(st.tuples(st.booleans(), st.booleans(), st.binary(max_size=2000)), max_size=12),
    st.lists(st.integers(1, 700), min_size=1, max_size=10),
)
def test_any_deflated_messages_in_any_cuts_read_back(keeps_context, messages, cuts):
    """Messages compressed or not (ws leaves the small ones as they are), each on its own or with the client's
    context kept; some repeat the one before, so that a kept context is pointed back into."""
    compressor = zlib.compressobj(6, zlib.DEFLATED, -15)
    frames, expected = [], []
    for compressed, repeats, payload in messages:
        text = (expected[-1] if expected and repeats else "") + payload.hex()
        data = text.encode()
        if compressed:
            frames.append(client_frame(client_deflated(data, compressor if keeps_context else None), rsv1=True))
        else:
            frames.append(client_frame(data))
        expected.append(text)
    data, reader, got, at, index = b"".join(frames), ws.FrameReader(1 << 20, deflate=True), [], 0, 0
    while at < len(data):
        size = cuts[index % len(cuts)]
        reader.receive(data[at : at + size])
        got += [payload for _, payload, _ in events(reader)]
        at, index = at + size, index + 1
    assert got == expected


def test_a_small_deflated_message_is_unpacked_a_slice_at_a_time_and_refused_once_over_its_limit():
    """A 30 kB message that unpacks to 31 MB: the reader unpacks it INFLATE_SLICE bytes per event, each weighing
    that (the shell's budget counts them and serves the other clients between them), and stops as soon as it has
    more than max_inflated (not the frames' bound, four times that)."""
    bomb = client_deflated(bytes(31_000_000))
    assert len(bomb) < 31_000
    reader = ws.FrameReader(4_000_000, deflate=True, max_inflated=1_000_000)
    reader.receive(client_frame(bomb, rsv1=True))
    slices = []
    tracemalloc.start()
    try:
        with pytest.raises(ws.ProtocolError) as refused:
            while True:
                slices.append(reader.next_event())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert refused.value.code == ws.TOO_BIG
    assert all(kind == ws.PART and size == ws.INFLATE_SLICE for kind, _, size in slices)
    assert len(slices) == 1_000_000 // ws.INFLATE_SLICE
    assert peak < 2_500_000, peak  # (1 MB unpacked, and the message's copy of it, at most)


@pytest.mark.parametrize(
    "parts",
    [
        (b"",),
        (b"x",),
        (os.urandom(1000),),
        (b'{"op":"publish"}' * 1000,),
        (b'{"op":"publish","msg":{"data":"', base64.b64encode(os.urandom(300_000)), b'"}}'),
    ],
)
def test_what_the_server_deflates_a_fresh_inflater_unpacks(parts):
    whole = b"".join(parts)
    for max_bits in (9, 12, 15):
        bits = ws.message_window_bits(len(whole), max_bits)
        assert 9 <= bits <= max_bits
        packed = ws.deflate_message(parts, bits)
        # an inflater with only that window unpacks it: the message stays within the window negotiated
        assert zlib.decompressobj(-bits).decompress(packed + b"\x00\x00\xff\xff") == whole
    assert ws.message_window_bits(100, 15) == 9 and ws.message_window_bits(1 << 20, 15) == 15


def test_a_cameras_base64_deflates_to_well_under_its_size():
    noise = bytes(random.Random(1).choice(range(96, 160)) for _ in range(200_000))  # a grainy picture's bytes
    text = b'{"op":"publish","msg":{"data":"' + base64.b64encode(noise) + b'"}}'
    assert len(ws.deflate_message((text,), 15)) < 0.8 * len(text)


def test_server_frames():
    assert ws.frame_header(5, ws.TEXT) == b"\x81\x05"
    assert ws.frame_header(300, ws.BINARY) == b"\x82\x7e\x01\x2c"
    assert ws.frame_header(70_000, ws.TEXT, compressed=True) == b"\xc1\x7f" + struct.pack("!Q", 70_000)
    assert [ws.SHORT_BINARY_HEADERS[n] for n in (0, 61, 125)] == [ws.frame_header(n, ws.BINARY) for n in (0, 61, 125)]
    assert len(ws.SHORT_BINARY_HEADERS) == ws.SHORT_PAYLOAD == 126
    assert ws.close_frame(1009, "message too big") == b"\x88\x11\x03\xf1message too big"
    assert ws.close_frame() == b"\x88\x00"
    assert ws.control_frame(ws.PONG, b"hi") == b"\x8a\x02hi"


# ---- the budget over a reader -------------------------------------------------------------------------
def test_a_flood_is_taken_in_turns_and_nothing_more_is_read_meanwhile():
    """As the shell does: frames are taken until the budget ends the turn; the next read happens only when
    the reader is empty, so what the bridge holds stays within one read however the budget answers."""
    clock = [0.0]
    budget = ClientBudget(0, 0, lambda: clock[0])  # no rate limit: every answer is "0 s, the others' turn"
    reader, read_size, flood = ws.FrameReader(1000), 65536, client_frame(b"", ws.PING) * 100_000
    at, turns, most_held, pongs = 0, 0, 0, 0
    while at < len(flood) or reader.buffered:
        event = reader.next_event()
        if event is None:
            reader.receive(flood[at : at + read_size])
            at += read_size
            most_held = max(most_held, reader.buffered)
            continue
        pongs += 1
        if budget.after_frame(event[2]) is not None:
            turns += 1
    assert pongs == 100_000 and turns == 100_000 // FRAMES_PER_TURN
    assert most_held < read_size + 6  # (one read, and the start of a 6-byte frame)


def test_a_message_in_many_empty_parts_costs_constant_time_per_part_and_is_bounded():
    reader = ws.FrameReader(100_000)
    reader.receive(client_frame(b"", fin=False))
    empty_part = client_frame(b"", ws.CONTINUATION, fin=False)
    with pytest.raises(ws.ProtocolError) as refused:
        for _ in range(100_000 // ws.PART_COST + 1):
            reader.receive(empty_part)
            assert reader.next_event()[0] == ws.PART
    assert refused.value.code == ws.TOO_BIG


def test_the_last_frame_taken_leaves_nothing_behind():
    reader = ws.FrameReader(1 << 20)
    reader.receive(client_frame(b"x" * 500_000, ws.BINARY))
    assert reader.next_event()[0] == ws.BINARY
    assert reader.buffered == 0 and len(reader._buffer) == 0


def test_after_a_client_ends_its_deflate_stream_its_next_messages_still_unpack():
    reader = ws.FrameReader(1 << 20, deflate=True)
    final = zlib.compressobj(9, zlib.DEFLATED, -15)
    ended = final.compress(b'{"op":"a"}') + final.flush(zlib.Z_FINISH)  # a final block (RFC 7692 7.2.3.4)
    reader.receive(client_frame(ended, rsv1=True) + client_frame(client_deflated(b'{"op":"b"}'), rsv1=True))
    assert [payload for _, payload, _ in events(reader)] == ['{"op":"a"}', '{"op":"b"}']


def test_what_follows_a_final_block_within_its_message_is_passed_over():
    final = zlib.compressobj(9, zlib.DEFLATED, -15)
    ended = final.compress(b'{"op":"a"}') + final.flush(zlib.Z_FINISH)
    reader = ws.FrameReader(1 << 22, deflate=True)
    reader.receive(
        client_frame(ended, fin=False, rsv1=True)
        + client_frame(os.urandom(300_000), ws.CONTINUATION, fin=False)
        + client_frame(b"more", ws.CONTINUATION)
        + client_frame(client_deflated(b'{"op":"b"}'), rsv1=True)
    )
    assert [payload for kind, payload, _ in events(reader) if kind != ws.PART] == ['{"op":"a"}', '{"op":"b"}']


def test_deflated_data_that_cannot_be_unpacked_is_the_clients_error():
    reader = ws.FrameReader(1 << 20, deflate=True)
    reader.receive(client_frame(b"\xff\xff\xff", rsv1=True))
    with pytest.raises(ws.ProtocolError) as refused:
        reader.next_event()
    assert refused.value.code == ws.INVALID_DATA


def unfinished(reader, data):
    reader.receive(data)
    return events(reader)


def test_a_message_still_arriving_is_unfinished_from_its_first_byte_until_its_last_frame():
    clock = [10.0]
    reader = ws.FrameReader(1 << 20, clock=lambda: clock[0])
    assert unfinished(reader, client_frame(b"whole")) == [(ws.TEXT, "whole", 5)]
    assert reader.unfinished_since is None
    first = client_frame(b"one ", fin=False)
    assert unfinished(reader, first[:3]) == [] and reader.unfinished_since == 10.0  # (a frame begun)
    clock[0] = 11.0
    assert unfinished(reader, first[3:]) == [(ws.PART, None, 4)]
    assert unfinished(reader, client_frame(b"", ws.PING)) == [(ws.PING, b"", 0)]  # (a ping in between)
    assert reader.unfinished_since == 10.0
    assert unfinished(reader, client_frame(b"two", ws.CONTINUATION)) == [(ws.TEXT, "one two", 3)]
    assert reader.unfinished_since is None
    clock[0] = 12.0
    assert unfinished(reader, client_frame(b"", ws.PING) + client_frame(b"x" * 1000)[:500])[0][0] == ws.PING
    assert reader.unfinished_since == 12.0


def test_unfinished_messages_of_every_client_share_one_bound():
    """Beyond OWN_BYTES each, what readers hold of their unfinished messages (parts, or a frame being received)
    counts against a SharedBound: the reader whose message would go beyond it is refused, and a reader closed
    (its connection gone) or done with its message gives its share back."""
    shared = ws.SharedBound(900_000)
    part = client_frame(bytes(300_000), fin=False)
    holding, frame_begun, refused = (ws.FrameReader(1 << 22, shared=shared) for _ in range(3))
    assert (
        unfinished(holding, part + client_frame(bytes(300_000), ws.CONTINUATION, fin=False))
        == [(ws.PART, None, 300_000)] * 2
    )
    assert shared.held == 600_000 - ws.OWN_BYTES
    big = client_frame(bytes(2_000_000), ws.BINARY)
    assert unfinished(frame_begun, big[:400_000]) == []
    held = 1_000_000 - 2 * ws.OWN_BYTES
    assert shared.held == held
    with pytest.raises(ws.ProtocolError) as refusal:
        unfinished(refused, part)
    assert refusal.value.code == ws.TRY_AGAIN
    unfinished(ws.FrameReader(1 << 22, shared=shared), client_frame(bytes(ws.OWN_BYTES - 100), fin=False))
    assert shared.held == held  # (within its own bytes: nothing)
    holding.close()
    assert unfinished(frame_begun, big[400_000:]) == [(ws.BINARY, bytes(2_000_000), 2_000_000)]
    assert shared.held == 0
    again = ws.FrameReader(1 << 22, shared=shared)
    assert unfinished(again, part)[0][0] == ws.PART


def test_a_reader_stalled_in_its_message_makes_way_for_one_whose_bytes_keep_coming():
    """When the shared bound is full, the holders that received fewer bytes lately (the last RECENT to 2 * RECENT
    seconds) than the one asking are evicted, slowest first: a stalled client's message (its reader closed, the
    shell told) makes way for a client sending; one sending as fast does not, and then the one asking is
    refused."""
    clock = [100.0]
    shared = ws.SharedBound(2_000_000, clock=lambda: clock[0])
    evicted = []
    stalled, trickling, sending, late = (
        ws.FrameReader(1 << 23, shared=shared, clock=lambda: clock[0], evicted=lambda name=name: evicted.append(name))
        for name in ("stalled", "trickling", "sending", "late")
    )
    big = client_frame(bytes(3_000_000))
    assert unfinished(stalled, big[:1_000_000]) == [] and unfinished(trickling, big[:900_000]) == []
    clock[0] += 2 * ws.RECENT
    assert unfinished(trickling, big[900_000:900_010]) == []  # (a few bytes now and then)
    assert unfinished(sending, big[: ws.OWN_BYTES + 50_000]) == []  # (room left: nobody makes way)
    assert evicted == [] and shared.held == 1_000_000 + 900_010 + 50_000 - 2 * ws.OWN_BYTES
    assert unfinished(sending, big[ws.OWN_BYTES + 50_000 : 1_000_000]) == []
    assert evicted == ["stalled"] and stalled.buffered == 0  # (the slowest, and enough)
    assert shared.held == 900_010 + 1_000_000 - 2 * ws.OWN_BYTES
    assert unfinished(sending, big[1_000_000:2_000_000]) == []
    assert evicted == ["stalled", "trickling"]
    with pytest.raises(ws.ProtocolError) as refusal:  # (as fast as `sending`, which holds the rest: refused)
        unfinished(late, big[:1_500_000])
    assert refusal.value.code == ws.TRY_AGAIN and evicted == ["stalled", "trickling"]
    assert unfinished(sending, big[2_000_000:]) == [(ws.TEXT, "\0" * 3_000_000, 3_000_000)]
    assert shared.held == 0
