// A picture from a sensor_msgs/CompressedImage (jpeg or png, decoded by the browser) or a sensor_msgs/Image
// (rgb8, bgr8, mono8, 16UC1 depth as grey), with frames per second and the age of the frame. It asks for binary
// CBOR frames, and for the newest frame only once the page has read the last (throttle_rate with queue_length 1),
// so the picture never lags behind on a slow link.
const FRAME_MS = 33;  // at most ~30 frames per second to this page
const STATS_MS = 1000;

export class ImageViewer {
  static subscription = { compression: 'cbor', throttle_rate: FRAME_MS, queue_length: 1 };

  constructor(element, { type }) {
    this.type = type;
    element.innerHTML = '<canvas class="camera" width="320" height="240" role="img" aria-label="Camera picture">' +
      '</canvas><p class="camera-stats ok" aria-live="off"></p>';
    [this.canvas, this.stats] = element.children;
    this.frames = [];  // arrival times, last second
    this.age = null;
    this.problem = null;  // why the last frame could not be drawn
    this.timer = setInterval(() => this.showStats(), STATS_MS);
  }

  async draw(message) {
    this.frames.push(performance.now());
    const stamp = message.header?.stamp;
    this.age = ageOf(stamp);
    try {
      const picture = this.type === 'sensor_msgs/CompressedImage' ? await decodeCompressed(message)
        : decodeRaw(message);
      this.canvas.width = picture.width;
      this.canvas.height = picture.height;
      const context = this.canvas.getContext('2d');
      if (picture instanceof ImageData) context.putImageData(picture, 0, 0);
      else context.drawImage(picture, 0, 0);
      this.problem = null;
      // Each frame drawn, with its age then, for whoever measures the page.
      this.canvas.dispatchEvent(new CustomEvent('frame', { detail: { age: ageOf(stamp) } }));
    } catch (error) {
      this.problem = error.message;
    }
  }

  showStats() {
    const now = performance.now();
    this.frames = this.frames.filter(t => t > now - 1000);
    const age = this.age === null ? '' : ` · frame age ${(this.age * 1000).toFixed(0)} ms`;
    this.stats.textContent = this.problem ?? `${this.frames.length} fps${age}`;
    this.stats.className = `camera-stats ${this.problem ? 'error' : 'ok'}`;
  }

  close() {
    clearInterval(this.timer);
  }
}

// Seconds since a header stamp (null without one).
function ageOf(stamp) {
  return stamp && stamp.secs ? Date.now() / 1000 - (stamp.secs + stamp.nsecs / 1e9) : null;
}

function bytes(data) {
  return data instanceof Uint8Array ? data : Uint8Array.from(atob(data), c => c.charCodeAt(0));
}

function decodeCompressed(message) {
  const format = (message.format || 'jpeg').toLowerCase();
  const mime = format.includes('png') ? 'image/png' : 'image/jpeg';
  return createImageBitmap(new Blob([bytes(message.data)], { type: mime }));
}

function decodeRaw({ width, height, encoding, step, is_bigendian: bigEndian, data }) {
  const source = bytes(data);
  const image = new ImageData(width, height);
  const out = image.data;
  const pixel = {
    rgb8: (row, x) => [source[row + 3 * x], source[row + 3 * x + 1], source[row + 3 * x + 2]],
    bgr8: (row, x) => [source[row + 3 * x + 2], source[row + 3 * x + 1], source[row + 3 * x]],
    mono8: (row, x) => [source[row + x], source[row + x], source[row + x]],
    '16UC1': (row, x) => {  // depth in mm: 0..~8 m as black..white
      const i = row + 2 * x;
      const mm = bigEndian ? (source[i] << 8) | source[i + 1] : source[i] | (source[i + 1] << 8);
      const grey = Math.min(255, mm / 32);
      return [grey, grey, grey];
    },
  }[encoding];
  if (!pixel) throw new Error(`Image encoding ${encoding} is not shown (rgb8, bgr8, mono8, 16UC1 are).`);
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < width; x++) {
      const [r, g, b] = pixel(y * step, x);
      const o = 4 * (y * width + x);
      out[o] = r;
      out[o + 1] = g;
      out[o + 2] = b;
      out[o + 3] = 255;
    }
  }
  return image;
}
