// A picture from a sensor_msgs/CompressedImage (jpeg or png, decoded by the browser) or a sensor_msgs/Image
// (rgb8, bgr8, mono8, 16UC1 depth as grey), with its frames per second, its age and its size.
//
// It comes by the bridge's MJPEG stream when the bridge serves one (RosSession.streaming): JPEG encoded on the
// bridge once per frame, size and quality, and with adaptive=1 the bridge picks the size and quality that keep the
// frame rate on the link it measures, sending the newest frame only. The stream is read here (fetch, multipart)
// rather than given to an <img>, so that each frame is counted and aged by its X-Timestamp. Without a stream (a
// bridge from elsewhere, or a topic it cannot stream) the messages come over the websocket as binary CBOR, the
// newest frame only once the page has read the last (throttle_rate with queue_length 1).
//
// Either way the page decodes one frame at a time (off the main thread for JPEG and PNG) and, while it does, keeps
// only the newest that arrives: what is drawn is as fresh as the link allows, never a backlog.
import { formatAge, formatBytes } from '../format.js';

const FRAME_MS = 33;  // at most ~30 frames per second to this page over the websocket
const STATS_MS = 1000;
const RETRY_MS = 1000;  // a stream that ended is asked for again after this, doubling up to MAX_RETRY_MS while it
const MAX_RETRY_MS = 8000;  // brings no frame
const STREAM_PARAMS = { adaptive: 1 };  // the bridge adapts size and quality to the link
// While the picture comes by its stream, the host's own subscription (an opened topic's tree and rate) takes a
// message a second, as binary CBOR: the pictures are not sent twice.
const BESIDE_A_STREAM = { compression: 'cbor', throttle_rate: 1000, queue_length: 1 };

export class ImageViewer {
  static subscription = { compression: 'cbor', throttle_rate: FRAME_MS, queue_length: 1 };

  // onDrawn (registry.js): each picture drawn that came by the stream, not by the host's subscription.
  constructor(element, { topic, type, onChange = () => {}, onDrawn = () => {} }) {
    this.topic = topic;
    this.type = type;
    this.onChange = onChange;
    this.onDrawn = onDrawn;
    element.innerHTML = '<canvas class="camera" width="320" height="240" role="img" aria-label="Camera picture">' +
      '</canvas><p class="camera-stats ok" aria-live="off"></p>';
    [this.canvas, this.stats] = element.children;
    this.session = null;
    this.stream = null;  // the stream being read, if any
    this.streamed = false;  // the pictures come by the bridge's stream (not by the messages given to draw())
    this.retry = null;
    this.retryMs = RETRY_MS;
    this.pending = null;  // the newest frame not drawn yet: { decode() -> picture, stamp, size, via }
    this.decoding = false;
    this.frames = [];  // when each frame was drawn (ms), the last second's
    this.shown = null;  // the frame last drawn: { age (s, at draw time) or null, drawnAt, stamp, size, width, height, via }
    this.problem = null;  // why the last frame could not be drawn, or the stream could not be read
    this.timer = setInterval(() => this.showStats(), STATS_MS);
    this.visibility = () => this.onVisibility();
    document.addEventListener('visibilitychange', this.visibility);
  }

  // What the host's subscription should ask for now (see registry.js).
  get subscription() {
    return this.streamed ? BESIDE_A_STREAM : ImageViewer.subscription;
  }

  attach(session) {
    this.detach();
    this.session = session;
    if (session.streaming) this.startStream();
  }

  detach() {
    clearTimeout(this.retry);
    this.stream?.close();
    this.stream = null;
    this.session = null;
  }

  // A page in the background (another tab, a phone's screen off) reads no stream: the link is left to the rest.
  onVisibility() {
    if (!this.streamed || !this.session) return;
    if (document.hidden) {
      clearTimeout(this.retry);
      this.stream?.close();
      this.stream = null;
    } else if (!this.stream) {
      this.startStream();
    }
  }

  startStream() {
    const session = this.session;
    this.streamed = true;  // (the host reads `subscription` after attach(): no onChange() needed)
    if (document.hidden) return;  // (onVisibility starts it when the page is seen)
    this.stream = session.stream(this.topic, STREAM_PARAMS, {
      onFrame: ({ bytes, type, stamp, size }) => {
        this.retryMs = RETRY_MS;
        this.arrived({ decode: () => createImageBitmap(new Blob([bytes], { type })), stamp, size, via: 'JPEG stream',
          streamed: true });
      },
      onEnd: error => {
        if (session !== this.session) return;
        this.stream = null;
        if (error?.status >= 400 && error.status < 500 && error.status !== 408 && error.status !== 429) {
          // the bridge will not stream this topic (a type it cannot encode, say): its messages then
          this.problem = null;
          this.streamed = false;
          this.onChange();
          return;
        }
        if (error) this.problem = `The picture stream failed (${error.message}); asking again.`;
        this.retry = setTimeout(() => session === this.session && this.startStream(), this.retryMs);
        this.retryMs = Math.min(2 * this.retryMs, MAX_RETRY_MS);
      },
    });
  }

  draw(message) {
    if (this.streamed) return;  // (the stream brings the pictures; the host's messages are for its tree)
    const compressed = this.type === 'sensor_msgs/CompressedImage';
    this.arrived({
      decode: () => (compressed ? decodeCompressed(message) : decodeRaw(message)),
      stamp: message.header?.stamp ?? null,
      size: message.data?.byteLength ?? message.data?.length ?? 0,
      via: `${compressed ? (message.format || 'jpeg').split(/[;\s]/)[0] : message.encoding} by websocket`,
    });
  }

  arrived(frame) {
    this.pending = frame;  // (a frame still waiting is replaced: only the newest is drawn)
    if (!this.decoding) this.drawPending();
  }

  async drawPending() {
    this.decoding = true;
    while (this.pending) {
      const frame = this.pending;
      this.pending = null;
      try {
        const picture = await frame.decode();
        const { width, height } = picture;
        if (this.canvas.width !== width) this.canvas.width = width;
        if (this.canvas.height !== height) this.canvas.height = height;
        const context = this.canvas.getContext('2d');
        if (picture instanceof ImageData) context.putImageData(picture, 0, 0);
        else {
          context.drawImage(picture, 0, 0);
          picture.close();
        }
        const drawnAt = performance.now();
        const age = this.ageOf(frame.stamp);
        this.frames.push(drawnAt);
        this.shown = { age, drawnAt, width, height, size: frame.size, via: frame.via };
        this.problem = null;
        // Each frame drawn, with its age then, for whoever measures the page.
        this.canvas.dispatchEvent(new CustomEvent('frame', { detail: { age } }));
        if (frame.streamed) {
          this.onDrawn({ stamp: frame.stamp, bytes: frame.size, noun: 'picture', via: "by the bridge's JPEG stream" });
        }
      } catch (error) {
        this.problem = error.message;
      }
    }
    this.decoding = false;
  }

  // Seconds since a stamp (ROS seconds, or {secs, nsecs}) by the bridge's clock as the session knows it; null
  // without a stamp.
  ageOf(stamp) {
    if (this.session) return this.session.ageOf(stamp);
    const seconds = typeof stamp === 'number' ? stamp : stamp ? stamp.secs + stamp.nsecs / 1e9 : 0;
    return seconds > 0 ? Date.now() / 1000 - seconds : null;
  }

  showStats() {
    const now = performance.now();
    this.frames = this.frames.filter(t => t > now - 1000);
    let text = `${this.frames.length} fps`;
    const shown = this.shown;
    if (shown) {
      // the age the newest frame had when drawn, plus the time it has been on screen since
      const age = shown.age === null ? '' : ` · ${formatAge(shown.age + (now - shown.drawnAt) / 1000)} old`;
      text += `${age} · ${shown.width}×${shown.height} · ${formatBytes(shown.size)} · ${shown.via}`;
    }
    this.stats.textContent = this.problem ?? text;
    this.stats.className = `camera-stats ${this.problem ? 'error' : 'ok'}`;
  }

  close() {
    clearInterval(this.timer);
    document.removeEventListener('visibilitychange', this.visibility);
    this.detach();
  }
}

function bytes(data) {
  return data instanceof Uint8Array ? data : Uint8Array.from(atob(data), c => c.charCodeAt(0));
}

function decodeCompressed(message) {
  const format = (message.format || 'jpeg').toLowerCase();
  const mime = format.includes('png') ? 'image/png' : 'image/jpeg';
  return createImageBitmap(new Blob([bytes(message.data)], { type: mime }));
}

// Into RGBA, one loop per encoding (no object per pixel: a 640x480 frame must not hold up the page's driving).
function decodeRaw({ width, height, encoding, step, is_bigendian: bigEndian, data }) {
  const source = bytes(data);
  const image = new ImageData(width, height);
  const out = image.data;
  const channels = { rgb8: 3, bgr8: 3, mono8: 1, '16UC1': 2 }[encoding];
  if (!channels) throw new Error(`Image encoding ${encoding} is not shown (rgb8, bgr8, mono8, 16UC1 are).`);
  if (source.length < step * (height - 1) + channels * width) throw new Error(`The ${encoding} picture is short.`);
  const [first, third] = encoding === 'bgr8' ? [2, 0] : [0, 2];
  for (let y = 0, o = 0; y < height; y++) {
    let i = y * step;
    for (let x = 0; x < width; x++, o += 4, i += channels) {
      if (channels === 3) {
        out[o] = source[i + first];
        out[o + 1] = source[i + 1];
        out[o + 2] = source[i + third];
      } else {
        // 16UC1: depth in mm, 0..~8 m as black..white
        const grey = channels === 1 ? source[i]
          : Math.min(255, (bigEndian ? (source[i] << 8) | source[i + 1] : source[i] | (source[i + 1] << 8)) / 32);
        out[o] = out[o + 1] = out[o + 2] = grey;
      }
      out[o + 3] = 255;
    }
  }
  return image;
}
