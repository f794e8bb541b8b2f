"""A message's JSON text wrapped for the wire, both ways: packed into a PNG image (`png` ops, `compression:
png`), and cut into `fragment` ops for a client's fragment_size."""

import base64
import io
import json
import math
import re

from PIL import Image

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
    return [
        {"op": "fragment", "id": id, "data": text[num * size : (num + 1) * size], "num": num, "total": total}
        for num in range(total)
    ]
