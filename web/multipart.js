// A multipart/x-mixed-replace body (an MJPEG stream, as web_video_server and the bridge's /stream send it) read as
// it arrives: push() each chunk as the network gives it, onPart({ headers, body }) is called for every whole part
// (headers: a Map of lower-case names; body: a Uint8Array of its own). A part with a Content-Length is copied once
// into its body as its bytes come, without a search; one without is found by the next boundary. Pure: no DOM.
const CR = 13;
const LF = 10;
const MAX_HEAD = 16 * 1024;  // bytes of boundary line and headers before a part's body: more is not a stream

export class MultipartReader {
  constructor(boundary, onPart) {
    this.onPart = onPart;
    this.boundary = `--${boundary}`;
    this.delimiter = latin1Bytes(`\r\n${this.boundary}`);
    this.pending = new Uint8Array(0);  // bytes read but not yet used: a part's head, or a body of unknown length
    this.searched = 0;  // how far pending has been searched for the delimiter (a body of unknown length)
    this.headers = null;  // the headers of the part being read
    this.body = null;  // its body, when its length is known, filled as its bytes come
    this.filled = 0;
    this.ended = false;  // the closing --boundary-- was read
  }

  push(chunk) {
    if (this.ended) return;
    if (this.body && !this.pending.length) {  // the usual case: a picture's bytes, copied straight into its body
      const n = this.fill(chunk);
      if (n === chunk.length) return;
      chunk = chunk.subarray(n);
    }
    this.pending = concat(this.pending, chunk);
    this.drain();
  }

  fill(bytes) {
    const n = Math.min(this.body.length - this.filled, bytes.length);
    this.body.set(bytes.subarray(0, n), this.filled);
    this.filled += n;
    if (this.filled === this.body.length) this.finish(this.body);
    return n;
  }

  drain() {
    while (!this.ended) {
      if (this.body) {
        if (!this.pending.length) return;
        this.pending = this.pending.subarray(this.fill(this.pending));
      } else if (this.headers) {  // a body of unknown length: everything up to the next delimiter
        const end = indexOf(this.pending, this.delimiter, Math.max(0, this.searched - this.delimiter.length));
        if (end < 0) {
          this.searched = this.pending.length;
          return;
        }
        const body = this.pending.slice(0, end);
        this.pending = this.pending.subarray(end + 2);  // "--boundary" starts the next part's head
        this.finish(body);
      } else if (!this.readHead()) {
        return;
      }
    }
  }

  // The boundary line and the headers up to their blank line; false until they are all here.
  readHead() {
    const bytes = this.pending;
    let start = 0;  // (the CRLF that ends the previous body, or blank lines before the first boundary)
    while (start + 1 < bytes.length && bytes[start] === CR && bytes[start + 1] === LF) start += 2;
    const end = indexOf(bytes, [CR, LF, CR, LF], start);
    if (end < 0) {
      const head = latin1Text(bytes.subarray(start, start + this.boundary.length + 2));
      if (head.startsWith(`${this.boundary}--`)) this.ended = true;
      else if (bytes.length - start > MAX_HEAD) throw new Error('not a multipart stream: no part headers');
      return false;
    }
    const lines = latin1Text(bytes.subarray(start, end)).split('\r\n');
    if (lines[0].startsWith(`${this.boundary}--`)) {
      this.ended = true;
      return false;
    }
    if (!lines[0].startsWith(this.boundary)) throw new Error('not a multipart stream: a part without its boundary');
    this.headers = new Map();
    for (const line of lines.slice(1)) {
      const colon = line.indexOf(':');
      if (colon > 0) this.headers.set(line.slice(0, colon).trim().toLowerCase(), line.slice(colon + 1).trim());
    }
    this.pending = bytes.subarray(end + 4);
    this.searched = 0;
    const length = this.headers.get('content-length');
    if (/^\d+$/.test(length ?? '')) {
      this.body = new Uint8Array(Number(length));
      this.filled = 0;
      if (!this.body.length) this.finish(this.body);
    }
    return true;
  }

  finish(body) {
    const headers = this.headers;
    this.body = null;
    this.headers = null;
    this.onPart({ headers, body });
  }
}

// The boundary of a Content-Type such as multipart/x-mixed-replace;boundary=frame (null if none).
export function boundaryOf(contentType) {
  const match = /boundary=(?:"([^"]+)"|([^;\s]+))/i.exec(contentType || '');
  return match ? match[1] ?? match[2] : null;
}

function concat(a, b) {
  if (!a.length) return b.slice();
  const joined = new Uint8Array(a.length + b.length);
  joined.set(a);
  joined.set(b, a.length);
  return joined;
}

function indexOf(bytes, pattern, from) {
  const first = pattern[0];
  for (let i = bytes.indexOf(first, from); i >= 0 && i + pattern.length <= bytes.length;
    i = bytes.indexOf(first, i + 1)) {
    let j = 1;
    while (j < pattern.length && bytes[i + j] === pattern[j]) j++;
    if (j === pattern.length) return i;
  }
  return -1;
}

function latin1Bytes(text) {
  return Uint8Array.from(text, c => c.charCodeAt(0));
}

function latin1Text(bytes) {
  return String.fromCharCode(...bytes);
}
