"""What waits for a client's socket: its Outbox, whole messages, small before big, each topic kept fresh while the
socket is backed up, bounded per client and for all clients together (QueuePool); and OutboxSession, the outgoing
half of every protocol's session around it."""

import collections
import itertools

from rosbridge import heap
from rosbridge.codec import BIG_BYTES
from rosbridge.protocol.encoded import SplicedFrame

SMALL_MESSAGE = 1 << 16  # bytes: a message smaller than this goes before the big ones that have not started yet
OWN_QUEUE_BYTES = 1 << 18  # what one client's outbox may hold before it draws on the bound shared by all clients'
# (QueuePool): the small backlogs of many clients never do
TOPIC_BACKLOG_BYTES = 16 * 1024  # what one topic may have waiting while the socket is backed up (but its newest)...
FRESH_HORIZON = 0.5  # ...and for how long (s): older messages of a topic that has a newer one waiting are skipped
REPORT_INTERVAL = 1.0  # s: how often at most a client is told what its slow link skipped or dropped
# A buffer of BIG_BYTES or more goes to the socket by reference (transport/connection.py), so every client it goes
# to holds the same one: the pool counts it once (ten clients that never read holding the same 30 MB mesh four
# times each counted 1.2 GB against a 128 MB pool, and every big message to anyone was dropped)


def shared_buffers(frame):
    """The big buffers of a frame that each client it goes to holds by reference, not as a copy of its own: the
    frame itself (encoded once for all its clients), or a spliced frame's big parts (an image's bytes behind each
    client's own head). A str frame is encoded anew for each client as it is taken: none."""
    if isinstance(frame, SplicedFrame):
        return tuple(part for part in frame.parts if len(part) >= BIG_BYTES)
    if isinstance(frame, str) or len(frame) < BIG_BYTES:
        return ()
    return (frame,)


def _shared(frames):
    """The shared buffers of a message's frames (or of one-frame messages), all together."""
    return tuple(itertools.chain.from_iterable(map(shared_buffers, frames)))


class _Unit:
    """One message's frames (its fragments, or its one frame) waiting for the socket; `shared`, the big buffers
    among them that the pool holds (counted once for every client), `own` the rest of its bytes."""

    __slots__ = ("key", "frames", "size", "queued_at", "big", "shared", "own")

    def __init__(self, key, frames, size, queued_at, big, shared, own):
        self.key, self.frames, self.size, self.queued_at, self.big = key, frames, size, queued_at, big
        self.shared, self.own = shared, own


class QueuePool:
    """What the outboxes of every client may hold together: `limit` bytes of
    - the big buffers that clients hold by reference (shared_buffers), each counted once however many hold it;
    - and beyond OWN_QUEUE_BYTES each, the rest, handed out as an outbox needs it and given back as it drains;
    so that clients that do not read cannot hold their whole bound each."""

    def __init__(self, limit):
        self.limit, self.granted = limit, 0
        self._buffers = heap.SharedBuffers()

    @property
    def shared(self):
        """Bytes of the distinct buffers held."""
        return self._buffers.bytes

    def grant(self, wanted):
        """Up to `wanted` more bytes for one outbox: what is left of the limit, at most."""
        given = max(0, min(wanted, self.limit - self.granted - self.shared))
        self.granted += given
        return given

    def give_back(self, count):
        self.granted -= count

    def hold(self, buffers):
        """Holds each buffer once more; False, holding none, if those nobody holds yet do not fit."""
        new = {id(buffer): len(buffer) for buffer in buffers if buffer not in self._buffers}
        if new and self.granted + self.shared + sum(new.values()) > self.limit:
            return False
        for buffer in buffers:
            self._buffers.hold(buffer)
        return True

    def release(self, buffers):
        for buffer in buffers:
            self._buffers.release(buffer)


class Outbox:
    """What waits for one websocket client's socket, as whole messages: a message's fragments are sent together
    or not at all. Pure: the server says when the socket is backed up (`backed_up`), and takes frames.

    - A client that keeps up gets everything, in order per topic.
    - Small messages go before big ones that have not started (a pose is not made to wait behind a picture),
      and between the fragments of a big one (rosbridge fragments are ops of their own): two lanes, small
      first; a topic's small message that follows a big one of the same topic waits in the big lane behind it,
      so that a topic's messages never change order.
    - While the socket is backed up, each topic keeps what is fresh: of its waiting messages, the older ones are
      skipped once they are more than TOPIC_BACKLOG_BYTES or older than FRESH_HORIZON, the newest always kept
      (a camera keeps one picture; a small topic the last half second). Messages without a topic (key None:
      service responses, status) are never skipped.
    - Bounds for everything: max_frames and max_bytes. Beyond them the oldest whole messages are dropped; a
      message larger than the whole bound is refused. Skipped, dropped and refused are counted by topic for the
      client's status messages (take_report). A message counts its bytes as encoded: one that goes deflated to
      a slow link is deflated once taken (transport/connection.py), so its smaller size never lets more wait here; its
      deflated copy lives with the frame (transport/slow_link.deflated_payload).
    - With a `pool` (a QueuePool shared by every client's outbox), what waits beyond OWN_QUEUE_BYTES, and what
      the socket was given but has not sent (in_flight, from set_backed_up), must also be granted by the pool:
      beyond what it grants, whole messages are dropped as above, the newest too. The big buffers that clients
      hold by reference are held in the pool instead, once for all, from their push (or take_at_once) until they
      have left (the socket has drained: set_backed_up(False), which the transport says after it wrote a big frame
      whole too)."""

    def __init__(self, max_frames, max_bytes, clock, pool=None):
        self.max_frames, self.max_bytes, self._clock = max_frames, max_bytes, clock
        self._pool, self._granted, self._in_flight = pool, 0, 0
        # what of self.bytes the pool does not hold (all of it without a pool), and what it may be before the
        # oldest messages are dropped: max_bytes, or with a pool what it granted
        self._own = 0
        self._allowed = max_bytes if pool is None else min(max_bytes, OWN_QUEUE_BYTES)
        self._sent, self._sent_bytes = [], 0  # the pool's holds of the buffers taken that may not have left yet
        # Small one-frame messages queued while nothing else waits and the socket keeps up, as (key, frame, size),
        # oldest first: what a client that keeps up is sent, taken in order without the lanes' bookkeeping
        # (a unit, its topic's queue, a clock read). Anything else queued, or the socket backing up, makes them
        # units first (_settle): while some pass, no unit waits.
        self._passing = collections.deque()
        self._small, self._big = collections.deque(), collections.deque()  # units, oldest first
        self._dead = 0  # units skipped or dropped that are still in a lane (removed lazily)
        self._by_key = {}  # topic (or None) -> its waiting units, oldest first
        self._key_bytes = {}  # topic -> bytes of its waiting units (a dict: a Counter's missing key costs a call)
        self._current = collections.deque()  # the rest of the fragments of the message being sent...
        self._current_key = None  # ...and its topic: only small messages of other topics go between them
        self.frames = 0  # frames waiting, the current message's included
        self.bytes = 0
        self.backed_up = False
        self.skipped, self.dropped, self.refused = collections.Counter(), collections.Counter(), collections.Counter()
        self._reported_at = float("-inf")

    def __len__(self):
        return self.frames

    def push_frame(self, key, frame):
        """Queues a message of one frame (key: its topic, or None)."""
        if not (self._by_key or self._current or self.backed_up):
            size = len(frame)
            # (max_bytes too: _allowed is never above it, and with no unit waiting, bytes are all _own)
            if size < SMALL_MESSAGE and self.frames < self.max_frames and self._own + size <= self._allowed:
                self._passing.append((key, frame, size))
                self.frames += 1
                self.bytes += size
                self._own += size
                return
        self._push(key, (frame,))

    def take_at_once(self, frames):
        """The bytes of `frames` (one message's, or one-frame messages) if they may go to the socket now, as if queued
        and taken at once: nothing waits, the socket keeps up, nothing is left to report, and they are within the
        bounds. Their shared buffers (a big message's) are then held in the pool, as a taken message's are, until they
        have left (set_backed_up(False)). Else None, and nothing is held."""
        if self.frames or self.backed_up or self.skipped or self.dropped or self.refused:
            return None
        size = sum(map(len, frames))
        if len(frames) > self.max_frames:
            return None
        if size < SMALL_MESSAGE or self._pool is None or max(map(len, frames)) < SMALL_MESSAGE:  # (nothing to hold)
            return size if size <= self._allowed else None
        shared = _shared(frames)
        held = sum(map(len, shared))
        if size > self.max_bytes or size - held > self._allowed or not self._pool.hold(shared):
            return None
        self._taken(shared, held)
        return size

    def push_each(self, key, frames):
        """Queues messages of one frame each (a topic's, one read's), in order: as push_frame each, in one go
        while they all pass."""
        if not (self._by_key or self._current or self.backed_up):
            sizes = list(map(len, frames))
            size = sum(sizes)
            if (
                max(sizes) < SMALL_MESSAGE
                and self.frames + len(frames) <= self.max_frames
                and self._own + size <= self._allowed
            ):
                self._passing.extend(zip(itertools.repeat(key), frames, sizes))
                self.frames += len(frames)
                self.bytes += size
                self._own += size
                return
        for frame in frames:
            self.push_frame(key, frame)

    def push(self, key, frames):
        """Queues the frames of one message (key: its topic, or None)."""
        if len(frames) == 1:
            self.push_frame(key, frames[0])
        else:
            self._push(key, frames)

    def _push(self, key, frames):
        if self._passing:
            self._settle()
        size = sum(map(len, frames))
        if len(frames) > self.max_frames or size > self.max_bytes:
            self.refused[key] += 1
            return
        shared, own = (), size
        if self._pool is not None and size >= BIG_BYTES:
            shared = _shared(frames)
            if shared and not self._hold(shared):
                self.dropped[key] += 1
                return
            own -= sum(map(len, shared))
        waiting, unit = self._enqueue(key, frames, size, self._clock(), shared, own)
        self.frames += len(frames)
        self.bytes += size
        self._own += own
        if self.backed_up and key is not None:
            self._freshen(key, waiting, unit.queued_at)
        if self._over():
            self._bound(unit)

    def _enqueue(self, key, frames, size, now, shared, own):
        """A message's unit, in its lane and its topic's queue (already counted in frames, bytes and _own)."""
        waiting = self._by_key.get(key)
        if waiting is None:
            waiting = self._by_key[key] = collections.deque()
        # (a bool, not the current message's deque, which empties as it is sent: what follows stays behind it)
        big = size >= SMALL_MESSAGE or bool(waiting and waiting[-1].big or key == self._current_key and self._current)
        unit = _Unit(key, frames, size, now, big, shared, own)
        (self._big if big else self._small).append(unit)
        waiting.append(unit)
        self._key_bytes[key] = self._key_bytes.get(key, 0) + size
        return waiting, unit

    def _settle(self):
        """The messages passing become units, in their order (queued_at: now, a little after they came; it only
        matters once the socket is backed up)."""
        passing, self._passing = self._passing, collections.deque()
        now = self._clock()
        for key, frame, size in passing:
            self._enqueue(key, (frame,), size, now, (), size)

    def _over(self):
        return self.frames > self.max_frames or self.bytes > self.max_bytes or self._own > self._allowed

    def _hold(self, shared):
        """Has the pool hold a new message's shared buffers, dropping this client's oldest big messages while
        they do not fit; False if they still do not."""
        for unit in self._big:
            if self._pool.hold(shared):
                return True
            if unit.frames is not None and unit.shared:
                self._drop(unit)
        return self._pool.hold(shared)

    def set_backed_up(self, flag, in_flight=0):
        """Whether the socket is backed up (then each topic keeps only what is fresh), and how many bytes the
        socket holds that have not left yet (they count against the pool until they have)."""
        if self._passing:
            self._settle()
        self.backed_up, self._in_flight = flag, in_flight
        if self._pool is not None:
            if not flag and self._sent:
                self._release_sent()
            self._regrant()
            if self._over():
                self._bound(None)

    def _freshen(self, key, waiting, now):
        while len(waiting) > 1 and (
            self._key_bytes[key] > TOPIC_BACKLOG_BYTES or now - waiting[0].queued_at > FRESH_HORIZON
        ):
            self._remove(waiting.popleft())
            self.skipped[key] += 1

    def _bound(self, newest):
        if self._pool is not None:
            self._regrant()
        for lane in (self._big, self._small):  # the big ones first: they are what fills memory
            for unit in lane:
                if not self._over():
                    return
                if unit.frames is not None and unit is not newest:
                    self._drop(unit)
        if self._pool is not None and self._over() and newest is not None and newest.frames is not None:
            self._drop(newest)  # (what the pool did not grant)

    def _drop(self, unit):
        self._by_key[unit.key].remove(unit)
        self._remove(unit)
        self.dropped[unit.key] += 1

    def _regrant(self):
        """Holds as much of the pool as what waits (up to max_bytes) and what is in flight take beyond
        OWN_QUEUE_BYTES, or what is left of it, and gives back the rest: what the pool holds already (shared
        buffers, waiting or taken) not counted."""
        in_flight = max(0, self._in_flight - self._sent_bytes)
        wanted = max(0, min(self._own, self.max_bytes) + in_flight - OWN_QUEUE_BYTES)
        if wanted > self._granted:
            self._granted += self._pool.grant(wanted - self._granted)
        elif wanted < self._granted:
            self._pool.give_back(self._granted - wanted)
            self._granted = wanted
        self._allowed = min(self.max_bytes, OWN_QUEUE_BYTES + self._granted - in_flight)

    def _taken(self, shared, held):
        """Shared buffers the pool holds, `held` bytes, are taken: the holds go once they have left (_release_sent)."""
        self._sent.extend(shared)
        self._sent_bytes += held

    def _release_sent(self):
        """What was taken has left: the pool's holds on its buffers go."""
        self._pool.release(self._sent)
        self._sent.clear()
        self._sent_bytes = 0

    def _remove(self, unit):
        """Takes a waiting unit out of the counts; it leaves its lane when the lane is next taken from, or compacted
        once the dead outnumber the living (a client that never reads must not grow the lanes)."""
        self._forget(unit)
        if unit.shared:
            self._pool.release(unit.shared)
        unit.frames = None
        self._dead += 1
        if self._dead > 64 and self._dead > len(self._small) + len(self._big) - self._dead:
            self._small = collections.deque(u for u in self._small if u.frames is not None)
            self._big = collections.deque(u for u in self._big if u.frames is not None)
            self._dead = 0

    def _forget(self, unit):
        key = unit.key
        left = self._key_bytes[key] - unit.size
        if left:
            self._key_bytes[key] = left
        else:
            del self._key_bytes[key]
        if not self._by_key[key]:
            del self._by_key[key]
        self.frames -= len(unit.frames)
        self.bytes -= unit.size
        self._own -= unit.own

    def take_frames(self, most_bytes):
        """The next frames to send, in order: the next one, and while the frames taken come to less than
        most_bytes, those of the small messages after it that passed (queued while the socket kept up); none
        ([]) when nothing waits."""
        passing = self._passing
        if not passing:
            frame = self._take_queued()
            return [] if frame is None else [frame]
        frames, size = [], 0
        while passing and (size < most_bytes or not frames):
            _, frame, frame_size = passing.popleft()
            frames.append(frame)
            size += frame_size
        self.frames -= len(frames)
        self.bytes -= size
        self._own -= size
        return frames

    def _take_queued(self):
        """The next frame of the lanes (nothing passing waits), or None."""
        current = self._current
        unit = self._next_unit(self._small)
        if unit is None and not current:
            unit = self._next_unit(self._big)
        if unit is not None:
            self._by_key[unit.key].popleft()
            self._forget(unit)
            if len(unit.frames) == 1:
                if unit.shared:  # (held until the socket has it: _release_sent)
                    self._taken(unit.shared, unit.size - unit.own)
                return unit.frames[0]
            # its frames become the current message, counted as they wait, and are taken from there one by one
            self.frames += len(unit.frames)
            self.bytes += unit.size
            self._own += unit.own
            current.extend(unit.frames)
            self._current_key = unit.key
        elif not current:
            if self._granted:  # (drained: what it held of the pool goes back)
                self._regrant()
            return None
        frame = current.popleft()
        self.frames -= 1
        self.bytes -= len(frame)
        if self._pool is None:
            self._own -= len(frame)
            return frame
        # A fragment's shared buffers are taken with it, not before: the socket may drain between fragments, and
        # the holds of those still waiting must stay until they too have left.
        shared = shared_buffers(frame)
        held = sum(map(len, shared))
        self._own -= len(frame) - held
        if shared:
            self._taken(shared, held)
        return frame

    def _next_unit(self, lane):
        while lane:
            unit = lane.popleft()
            if unit.frames is not None:
                return unit
            self._dead -= 1
        return None

    def reports_due(self, config):
        """(level, text) of what the client's slow link cost it since it was last told (outbox_report), if there
        is something to tell and REPORT_INTERVAL has passed; else nothing."""
        if not (self.skipped or self.dropped or self.refused):  # (the usual case: no clock read at every frame)
            return ()
        now = self._clock()
        if now - self._reported_at < REPORT_INTERVAL:
            return ()
        self._reported_at = now
        return tuple(outbox_report(*self.take_report(), config))

    def take_report(self):
        """(skipped, dropped, refused) since the last report: Counters of messages by topic."""
        report = (self.skipped, self.dropped, self.refused)
        self.skipped, self.dropped, self.refused = collections.Counter(), collections.Counter(), collections.Counter()
        return report

    def clear(self):
        for unit in itertools.chain(self._small, self._big):
            if unit.frames is not None and unit.shared:
                self._pool.release(unit.shared)
        if self._pool is not None:
            self._pool.release(_shared(self._current))
        for lane in (self._small, self._big, self._current, self._passing):
            lane.clear()
        self._current_key = None
        self._by_key.clear()
        self._key_bytes.clear()
        self._dead = self.frames = self.bytes = self._own = self._in_flight = 0
        if self._pool is not None:
            self._release_sent()
            self._regrant()


class OutboxSession:
    """The outgoing half of a session, the same for every protocol (contract.ProtocolSession's backed_up,
    take_frames and close): the frames of each message wait in the client's Outbox. The first message queued after
    the host took the last frame wakes it (host.wake()), and it takes frames until take_frames gives none. While
    nothing waits, here or in the host, a read's messages (_queue_each) are not queued: the host writes them at
    once (host.write_now). What the client's slow link cost it goes first, at most once a REPORT_INTERVAL,
    as the protocol's report_frame makes it."""

    def __init__(self, config, host):
        self.config, self._host = config, host
        self.is_closed = False  # (nothing is queued once the client has left)
        self._outbox = Outbox(config.max_queue, config.max_queue_bytes, host.clock, config.queue_pool)
        self._reports: collections.deque = collections.deque()  # report frames: they go first
        self._woken = False

    def report_frame(self, level, text):
        """The frame that tells the client `text` (outbox_report's), or None if it is not to be told."""
        raise NotImplementedError

    def _queue(self, topic, frames):
        """Queues the frames of one message (topic None: not a topic's; such are never skipped)."""
        if not self.is_closed:
            self._outbox.push(topic, frames)
            if not self._woken:
                self._wake_host()

    def _queue_each(self, topic, frames):
        """Queues messages of one frame each (one read's), in order, as _queue. While nothing of this client's
        waits, here (Outbox.take_at_once) or in the host (host.may_write_now), the host writes them at once
        instead, in one write (host.write_now): no queueing, wake and take for a read, an image's too. (Not so in
        _queue: a rosbridge client's messages come one by one, and a read's would each be a write of its own.)"""
        if not self.is_closed:
            if (
                not self._woken
                and self._host.may_write_now()
                and (size := self._outbox.take_at_once(frames)) is not None
            ):
                self._host.write_now(frames, size)
                return
            self._outbox.push_each(topic, frames)
            if not self._woken:
                self._wake_host()

    def _wake_host(self):
        self._woken = True
        self._host.wake()

    def backed_up(self, flag, in_flight=0):
        """The host says whether the client's socket has stopped taking frames (then each topic keeps only what is
        fresh), and how many bytes it was given that have not left yet."""
        self._outbox.set_backed_up(flag, in_flight)

    def take_frames(self, most_bytes):
        """The next frames to write (Outbox.take_frames), or none ([]) when nothing waits (the next message queued
        wakes the host again)."""
        due = self._outbox.reports_due(self.config)
        if due:
            self._reports.extend(frame for frame in itertools.starmap(self.report_frame, due) if frame is not None)
        if self._reports:
            return [self._reports.popleft()]
        frames = self._outbox.take_frames(most_bytes)
        if not frames:
            self._woken = False
        return frames

    def close(self, reason):
        """Closes the connection once what is queued is sent."""
        self._host.close_after_sending(reason)


def outbox_report(skipped, dropped, refused, config):
    """(level, text) of each status telling a client what its slow link cost it."""

    def by_topic(counts):
        return ", ".join(f"{topic or 'other messages'} {n}" for topic, n in counts.most_common())

    if skipped:
        yield (
            "warning",
            (
                f"skipped {sum(skipped.values())} older message(s), the newest of each topic kept "
                f"(the link is slower than the messages): {by_topic(skipped)}"
            ),
        )
    if dropped:
        yield (
            "error",
            (
                f"dropped {sum(dropped.values())} whole message(s): client too slow (outgoing bound "
                f"{config.max_queue} frames, {config.max_queue_bytes} bytes; beyond {OWN_QUEUE_BYTES} bytes "
                f"each, {config.queue_pool.limit} bytes for all clients together): {by_topic(dropped)}"
            ),
        )
    if refused:
        yield (
            "error",
            (
                f"refused {sum(refused.values())} message(s) larger than the client's whole outgoing bound "
                f"({config.max_queue} frames, {config.max_queue_bytes} bytes): {by_topic(refused)}"
            ),
        )
