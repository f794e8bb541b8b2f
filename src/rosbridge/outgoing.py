"""A bounded queue of outgoing frames that drops the oldest when its reader is too slow: a websocket client's
(protocol.Session), and a ROS subscriber's of a topic the bridge publishes (ros_side/links.py)."""
import collections


class FrameQueue:
    """Frames (str or bytes) waiting for the socket, at most max_frames of them and max_bytes in all (the
    newest frame is always kept). Counts what it drops so that the client can be told."""

    def __init__(self, max_frames, max_bytes):
        self.max_frames, self.max_bytes = max_frames, max_bytes
        self._frames = collections.deque()
        self.bytes = 0
        self.dropped = 0

    def __len__(self):
        return len(self._frames)

    def push(self, frame):
        frames = self._frames
        frames.append(frame)
        self.bytes += len(frame)
        while len(frames) > 1 and (len(frames) > self.max_frames or self.bytes > self.max_bytes):
            self.bytes -= len(frames.popleft())
            self.dropped += 1

    def pop(self):
        """The oldest frame, or None."""
        if not self._frames:
            return None
        frame = self._frames.popleft()
        self.bytes -= len(frame)
        return frame

    def take_all(self):
        """Every frame waiting, oldest first; the queue is then empty."""
        frames = list(self._frames)
        self.clear()
        return frames

    def take_dropped(self):
        dropped, self.dropped = self.dropped, 0
        return dropped

    def clear(self):
        self._frames.clear()
        self.bytes = 0
