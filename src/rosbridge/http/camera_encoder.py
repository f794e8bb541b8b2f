"""The camera streams' encoder thread (Encoder), and how work is handed to it and back.

Threads (everything of the camera streams runs on the event loop but the encoding):
- the loop: the handlers, Streams, every StreamTopic, Frame (its `variants`, what was made of it) and viewer, and
  their streams;
- the encoder (Encoder, one thread): decodes a frame and makes the JPEGs asked of it (jpeg.Picture). A job gets the
  frame's Picture (which only the encoder touches; the loop only drops its reference) and a list of keys, and its
  results go back to the loop (IOLoop.add_callback) to be stored in the frame's variants. A topic has at most one
  job in flight: frames arriving meanwhile only replace the topic's newest frame, and the next job takes the newest
  frame for the viewers still waiting (newest wins), so a busy encoder costs frames, never a backlog. Topics take
  turns: the jobs run in the order they came, a topic's next job comes only once its last is done, and a job is
  small (at most stream_topics.MAX_KEYS_PER_JOB variants and JOB_PIXELS, or one variant, itself at most
  jpeg.MAX_OUTPUT_PIXELS), so a topic waits at most one turn of each other busy topic, and one topic's viewers,
  whatever sizes they ask, take at most the encoder's one core;
- master look-ups (a topic's type, the image topics) are the backend's /rosapi/topics call, on one of its
  service-call threads; the reply comes back on the loop (TopicTypes shares one look-up between requests)."""

import functools

from rosbridge.errors import log_bug
from rosbridge.http import jpeg
from rosbridge.off_loop import EncodingThread


class Encoder:
    """The encoder thread: makes the JPEGs asked of a frame (see the module's docstring for the hand-off)."""

    def __init__(self, loop):
        self._thread = EncodingThread(loop, "stream encoder")

    def submit(self, picture, keys, done):
        """done(results) runs on the loop: key -> ("image/jpeg", bytes) or jpeg.ImageError."""

        def finished(results):
            if results is None:  # a bug (logged): the viewers are told, and the topic's next job can start
                results = {key: jpeg.ImageError("the frame could not be encoded") for key in keys}
            done(results)

        self._thread.run(functools.partial(_encode, picture, keys), finished)


def _encode(picture, keys):
    """On the encoder thread. keys come sorted by size: each size is resized once."""
    results = {}
    for key in keys:
        size, quality, invert = key
        try:
            results[key] = ("image/jpeg", picture.jpeg(size, quality, invert))
        except jpeg.ImageError as error:
            results[key] = error
        except Exception as error:  # a bug (or a picture Pillow chokes on): the viewers are told, and it is logged
            log_bug("encoding a camera frame", error)
            results[key] = jpeg.ImageError(f"the frame could not be encoded ({type(error).__name__})")
    picture.forget_resized()
    return results
