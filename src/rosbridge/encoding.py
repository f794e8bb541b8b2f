"""The wire encodings of outgoing messages besides plain JSON text: CBOR (`compression: cbor`), JSON packed
into a PNG image (`compression: png`), and `fragment` ops for messages larger than a client's fragment_size."""
import base64
import io
import json
import math
import os
import re
import struct

import cbor2
from PIL import Image

from rosbridge.convert import encoder_factory, json_leaf_encoder

# RFC 8746 tags of the little-endian typed arrays, with the matching struct codes. uint8 arrays go as plain
# CBOR byte strings instead, as the reference sends them.
TYPED_ARRAY_TAGS = {
    "int8": (72, "b"), "uint16": (69, "H"), "int16": (77, "h"), "uint32": (70, "I"), "int32": (78, "i"),
    "uint64": (71, "Q"), "int64": (79, "q"), "float32": (85, "f"), "float64": (86, "d"),
}


def _typed_array(tag, code):
    return lambda items: cbor2.CBORTag(tag, struct.pack(f"<{len(items)}{code}", *items))


# bytes: a byte string this long (an image's data) is cheaper to write to the socket by reference, as a part of
# its frame, than to copy into one frame with the rest (frames.SplicedFrame)
BIG_BYTES = 1 << 16


class _Spliced:
    """A big byte string (an image's data), which cbor_parts leaves out of cbor2's output."""
    __slots__ = ("data",)

    def __init__(self, data):
        self.data = data


def _byte_string(value):
    if len(value) >= BIG_BYTES:
        return _Spliced(value)
    return value if isinstance(value, bytes) else bytes(value)


def _cbor_leaf_encoder(base, is_array):
    if not is_array:
        # CBOR carries NaN and +-Inf, so floats go as they are; time/duration as in JSON
        return None if base in ("float32", "float64") else json_leaf_encoder(base, is_array)
    if base == "uint8":
        return _byte_string
    if base in TYPED_ARRAY_TAGS:
        return _typed_array(*TYPED_ARRAY_TAGS[base])
    return json_leaf_encoder(base, is_array)


_cbor_encoder_for = encoder_factory(_cbor_leaf_encoder)


def to_cbor_value(msg):
    """The message as Python values for cbor2: like convert.to_json, but uint8[]/char[] as bytes, other
    numeric arrays (fixed or variable) as RFC 8746 little-endian typed arrays, and NaN/Inf kept."""
    return _cbor_encoder_for(type(msg))(msg)


def cbor_parts(obj):
    """`obj` (e.g. a publish op whose msg is to_cbor_value(...)) in CBOR, as parts to send one after another. cbor2
    encodes each big byte string as a 16-byte stand-in, whose place then holds the head of the real string and
    the bytes themselves, not copied: cbor2 alone takes over ten times longer."""
    try:
        return [cbor2.dumps(obj, default=_refuse_spliced)]
    except _HasSpliced:
        pass
    spliced = []

    def stand_in(encoder, value):
        _refuse_other(value)
        token = os.urandom(16)
        spliced.append((token, value.data))
        encoder.encode(token)

    encoded, parts, start = cbor2.dumps(obj, default=stand_in), [], 0
    for token, data in spliced:  # (in the order cbor2 wrote them)
        place = encoded.index(_bytes_head(16) + token, start)
        parts += (encoded[start:place] + _bytes_head(len(data)), data)
        start = place + 17
    parts.append(encoded[start:])
    return parts


class _HasSpliced(Exception):
    pass


def _refuse_spliced(encoder, value):
    _refuse_other(value)
    raise _HasSpliced


def _refuse_other(value):
    if not isinstance(value, _Spliced):
        raise cbor2.CBOREncodeTypeError(f"cannot serialize type {type(value).__name__}")


def _bytes_head(length):
    """The head of a CBOR byte string of `length` bytes (RFC 8949 section 3: major type 2, then the length)."""
    if length < 24:
        return bytes((0x40 | length,))
    for info, size in ((24, 1), (25, 2), (26, 4), (27, 8)):
        if length < 1 << (8 * size):
            return bytes((0x40 | info,)) + length.to_bytes(size, "big")
    raise ValueError(f"{length} bytes: too long for CBOR")


_NON_ASCII = re.compile(r"[^\x00-\x7f]")


def _escape_non_ascii(json_text):
    # roslibjs rebuilds the text with one String.fromCharCode per byte, which would garble UTF-8; JSON allows
    # non-ASCII characters only inside strings, where \uXXXX escapes mean the same.
    if json_text.isascii():
        return json_text
    return _NON_ASCII.sub(lambda match: json.dumps(match.group()).strip('"'), json_text)


def png_frame(text):
    """JSON `text` packed into an RGB PNG image, base64: the `data` of a `png` op.

    Its bytes fill the R, G, B channels of the pixels row by row, in a roughly square image; the last pixels
    are padded with newlines, which JSON.parse ignores. Non-ASCII characters are sent as \\u escapes."""
    data = _escape_non_ascii(text).encode("ascii")
    pixels = max(1, math.ceil(len(data) / 3))
    width = max(1, math.isqrt(pixels))
    height = math.ceil(pixels / width)
    image = Image.frombytes("RGB", (width, height), data.ljust(width * height * 3, b"\n"))
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


PNG_MAX_BYTES = 64 * 2**20


def png_unframe(data, max_bytes=PNG_MAX_BYTES):
    """The JSON text held in a png op's `data` (with the padding removed). Refuses, with ValueError, anything
    that is not such an image, or one that would unpack to more than max_bytes."""
    try:
        with Image.open(io.BytesIO(base64.b64decode(data, validate=True))) as image:
            width, height = image.size  # known from the header, before any pixel is unpacked
            if width * height * 3 > max_bytes:
                raise ValueError(f"the image would unpack to {width * height * 3} bytes, more than {max_bytes}")
            pixels = image.convert("RGB").tobytes()
        return pixels.rstrip(b"\n").decode("utf-8")
    except ValueError:
        raise
    except Exception as error:  # PIL reports broken images as OSError, SyntaxError, EOFError, zlib.error...
        raise ValueError(f"not a readable PNG image ({type(error).__name__}: {error})") from None


def fragments(text, size, id):
    """`text` cut into `fragment` ops of at most `size` characters each, numbered from 0."""
    if size < 1:
        raise ValueError(f"fragment size must be at least 1, got {size}")
    total = max(1, math.ceil(len(text) / size))
    return [{"op": "fragment", "id": id, "data": text[num * size:(num + 1) * size], "num": num, "total": total}
            for num in range(total)]
