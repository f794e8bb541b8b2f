// The page's one link to the bridge. Connection reconnects with backoff; each time it is connected it makes a
// RosSession, the only owner of ROSLIB objects and of the bridge's picture streams, and drops it when the socket
// goes: subscriptions and advertisements live on the server side of one socket, so every panel makes its own
// again on the next session.
import { MultipartReader, boundaryOf } from './multipart.js';

const FIRST_RETRY_MS = 500;
const MAX_RETRY_MS = 5000;
const CALL_TIMEOUT_S = 10;
const REFUSAL_MS = 500;  // a publish the bridge has not refused by then counts as published
const STREAMS_WAIT_MS = 3000;  // how long the bridge has to say it serves picture streams (/streams) at connection
const CLOCK_SAMPLES = 10;  // the clock is compared with the bridge's by the quickest of the last so many round trips

export class Connection {
  // onState(state, detail): state is 'connecting' | 'connected' | 'closed' | 'error'.
  // onSession(session): a new RosSession once connected, null when it is gone.
  constructor(url, { onState, onSession }) {
    this.url = url;
    this.onState = onState;
    this.onSession = onSession;
    this.retryMs = FIRST_RETRY_MS;
    this.everConnected = false;
    this.retrying = false;
  }

  start() {
    this.attempt();
  }

  attempt() {
    const ros = new ROSLIB.Ros();
    let session = null;
    let announced = false;  // the panels were given the session
    let ended = false;
    ros.on('connection', async () => {
      this.everConnected = true;
      this.retryMs = FIRST_RETRY_MS;
      this.retrying = false;
      session = new RosSession(ros, this.url);
      this.onState('connected', this.url);
      await session.start();  // (what the bridge serves besides the websocket is known before panels ask)
      if (ended) return;
      announced = true;
      this.onSession(session);
    });
    const end = () => {  // 'error' and 'close' may both fire for one failure
      if (ended) return;
      ended = true;
      ros.close();
      if (session) {
        session.close();
        if (announced) this.onSession(null);
      }
      const delay = this.retryMs;
      this.retryMs = Math.min(this.retryMs * 2, MAX_RETRY_MS);
      // Once we have been connected, losing the bridge reads as "closed" until it is back.
      this.retrying = true;
      this.onState(this.everConnected ? 'closed' : 'error', delay);
      setTimeout(() => this.attempt(), delay);
    };
    ros.on('close', end);
    ros.on('error', end);
    // Retries keep showing why we retry ("closed"/"error") instead of flickering to "connecting".
    if (!this.retrying) this.onState('connecting', this.url);
    ros.connect(this.url);
  }
}

// One connected socket's ROS objects, and the picture streams fetched beside it from the same bridge. Every
// callback it hands out is silenced once the session is closed, so that a late answer from a dead socket never
// reaches a panel that has moved on. It also keeps what the link health shows: the bytes received, and the
// bridge's clock as measured by round trips (ping()), by which header stamps are aged.
export class RosSession {
  constructor(ros, url = ros.socket?.url ?? '') {
    this.ros = ros;
    this.closed = false;
    this.topics = new Set();
    this.http = url.replace(/^ws/, 'http');  // the bridge's HTTP address: the websocket's, ws -> http, wss -> https
    this.streaming = false;  // whether the bridge serves picture streams (known once start() resolves)
    this.fetches = new Set();  // the AbortController of each stream being read
    // Bytes received: each websocket message's payload and each stream's body, as read by the page (the
    // network's own overhead, headers and compression are not seen from here: an approximation).
    this.received = 0;
    this.clockSamples = [];  // [round trip s, ROS time - this machine's time s], the latest CLOCK_SAMPLES
    ros.socket?.addEventListener?.('message', event => {
      const data = event.data;
      this.received += typeof data === 'string' ? data.length : data.byteLength ?? data.size ?? 0;
    });
    // The bridge tells a client at level warning what its slow link made it skip (only the newest message of a
    // topic kept); the default level, error, would hide that.
    ros.callOnConnection({ op: 'set_level', level: 'warning' });
  }

  // Asks whether the bridge serves picture streams (web_video_server's /streams); a bridge from elsewhere does
  // not, and the pictures then come over the websocket.
  async start() {
    const asked = new AbortController();
    const timer = setTimeout(() => asked.abort(), STREAMS_WAIT_MS);
    try {
      const answer = await fetch(new URL('streams?format=json', this.http), { signal: asked.signal, cache: 'no-store' });
      this.streaming = answer.ok && Boolean(await answer.json());
    } catch {
      this.streaming = false;
    } finally {
      clearTimeout(timer);
    }
  }

  // Reads the bridge's MJPEG stream of an image topic (/stream?topic=...&type=mjpeg and params, e.g. adaptive,
  // quality, width). onFrame({ bytes, type, stamp, size }) for each picture: its JPEG, its MIME type, its stamp in
  // ROS seconds (X-Timestamp: the header's, or when the bridge received it) or null; onEnd(error or null) when
  // the stream ends by itself (not after close()); a refused request's error has the HTTP `status`. The console
  // does not authenticate (it sends no rosauth), so neither do its streams. Returns { close() }.
  stream(topic, params, { onFrame, onEnd }) {
    const url = new URL('stream', this.http);
    for (const [key, value] of Object.entries({ topic, type: 'mjpeg', ...params })) url.searchParams.set(key, value);
    const asked = new AbortController();
    this.fetches.add(asked);
    const read = async () => {
      const answer = await fetch(url, { signal: asked.signal, cache: 'no-store' });
      if (!answer.ok) {
        const text = (await answer.text()).replace(/<[^>]*>/g, ' ').replace(/\s+/g, ' ').trim().slice(0, 200);
        throw Object.assign(new Error(`${answer.status} ${text || answer.statusText}`), { status: answer.status });
      }
      const boundary = boundaryOf(answer.headers.get('content-type'));
      if (!boundary) throw new Error(`not a picture stream (${answer.headers.get('content-type')})`);
      let failure = null;  // a stream that fails after its start says why in a last part, of text
      const parts = new MultipartReader(boundary, ({ headers, body }) => {
        const type = headers.get('content-type') || 'image/jpeg';
        if (type.startsWith('text/')) {
          failure = new Error(new TextDecoder().decode(body).trim());
          return;
        }
        if (this.closed || asked.signal.aborted) return;
        const stamp = Number.parseFloat(headers.get('x-timestamp'));
        onFrame({ bytes: body, type, stamp: Number.isFinite(stamp) && stamp > 0 ? stamp : null, size: body.length });
      });
      const reader = answer.body.getReader();
      for (;;) {
        const { done, value } = await reader.read();
        if (done) break;
        this.received += value.length;
        parts.push(value);
      }
      if (failure) throw failure;
    };
    read().then(() => null, error => error).then(error => {
      this.fetches.delete(asked);
      if (!asked.signal.aborted && !this.closed) onEnd(error);
    });
    return {
      close: () => {
        this.fetches.delete(asked);
        asked.abort();
      },
    };
  }

  // Times a cheap call (/rosapi/get_time) and compares the clocks by it; resolves with the round trip in s.
  async ping() {
    const sent = performance.now();
    const wall = Date.now() / 1000;
    const { time } = await this.rosapi('get_time');
    const roundTrip = (performance.now() - sent) / 1000;
    this.clockSamples.push([roundTrip, time.secs + time.nsecs / 1e9 - (wall + roundTrip / 2)]);
    if (this.clockSamples.length > CLOCK_SAMPLES) this.clockSamples.shift();
    return roundTrip;
  }

  // The ROS time now as this page reckons it: its own clock set by the quickest recent round trip to the bridge
  // (within half of it), or its own clock alone before the first.
  rosNow() {
    const best = this.clockSamples.reduce((a, b) => (b[0] < a[0] ? b : a), [Infinity, 0]);
    return Date.now() / 1000 + best[1];
  }

  // Seconds since a ROS stamp ({secs, nsecs} or seconds), or null for none (absent or zero).
  ageOf(stamp) {
    const seconds = typeof stamp === 'number' ? stamp : stamp ? stamp.secs + stamp.nsecs / 1e9 : 0;
    return seconds > 0 ? this.rosNow() - seconds : null;
  }

  // Subscribes; returns a handle whose close() unsubscribes. options: throttle_rate, queue_length, compression.
  subscribe(name, type, onMessage, options = {}) {
    const topic = new ROSLIB.Topic({ ros: this.ros, name, messageType: type, ...options });
    this.topics.add(topic);
    topic.subscribe(message => this.closed || onMessage(message));
    return {
      close: () => {
        if (!this.topics.delete(topic) || this.closed) return;
        topic.unsubscribe();
      },
    };
  }

  // A publisher. publish(message) sends a plain object and resolves once the bridge has had REFUSAL_MS to refuse
  // it, or rejects with the bridge's error (a status op carrying the id of this publisher's advertise or publish;
  // roslibjs emits it as 'status:<id>'). An error that comes when no publish waits goes to onError (e.g. the
  // advertise refused at once). close() unadvertises. The ops are sent here rather than by a ROSLIB.Topic, which
  // gives each publish a fresh id that its caller cannot know.
  advertise(name, type, { latch = false, queue_size = 100, onError = () => {} } = {}) {
    const [advertiseId, publishId] = ['advertise', 'publish'].map(op => `${op}:${name}:${++this.ros.idCounter}`);
    const advertise = () => this.ros.callOnConnection({ op: 'advertise', id: advertiseId, topic: name, type, latch,
      queue_size });
    const waiting = new Set();  // the reject of each publish still within REFUSAL_MS
    let refusal = null;  // the bridge's error for the advertise: the errors of the publishes that follow add nothing
    const fail = text => {
      if (!waiting.size) onError(text);
      for (const reject of waiting) reject(new Error(text));
      waiting.clear();
    };
    const listeners = {
      [`status:${advertiseId}`]: status => {
        if (this.closed || status.level !== 'error') return;
        refusal = status.msg;
        fail(status.msg);
      },
      [`status:${publishId}`]: status => this.closed || status.level !== 'error' || refusal || fail(status.msg),
    };
    for (const [event, listener] of Object.entries(listeners)) this.ros.on(event, listener);
    advertise();
    let open = true;
    return {
      publish: message => new Promise((resolve, reject) => {
        if (this.closed || !open) {
          reject(new Error('not connected'));
          return;
        }
        if (refusal !== null) {  // ask again: what stood in the way may be gone
          refusal = null;
          advertise();
        }
        this.ros.callOnConnection({ op: 'publish', id: publishId, topic: name, msg: message, latch });
        waiting.add(reject);
        setTimeout(() => {
          if (!waiting.delete(reject)) return;
          if (this.closed) reject(new Error('the connection closed'));
          else resolve();
        }, REFUSAL_MS);
      }),
      close: () => {
        if (!open) return;
        open = false;
        for (const [event, listener] of Object.entries(listeners)) this.ros.off(event, listener);
        if (!this.closed) this.ros.callOnConnection({ op: 'unadvertise', id: advertiseId, topic: name });
      },
    };
  }

  // Calls a service; resolves with the response, rejects with the bridge's error text.
  call(name, type, args = {}) {
    return new Promise((resolve, reject) => {
      if (this.closed) {
        reject(new Error('not connected'));
        return;
      }
      const service = new ROSLIB.Service({ ros: this.ros, name, serviceType: type });
      const timer = setTimeout(() => reject(new Error(`no answer from ${name} in ${CALL_TIMEOUT_S} s`)),
        CALL_TIMEOUT_S * 1000);
      service.callService(new ROSLIB.ServiceRequest(args), result => {
        clearTimeout(timer);
        if (!this.closed) resolve(result);
      }, error => {
        clearTimeout(timer);
        if (!this.closed) reject(new Error(error || `${name} failed`));
      });
    });
  }

  // An actionlib client over the server's five topics (ROSLIB.ActionClient): serverName like '/fibonacci',
  // actionName like 'actionlib/TestAction'. send(goal, { onStatus, onFeedback, onResult }) sends one goal and
  // returns { id, cancel() }; close() unsubscribes and unadvertises.
  actionClient(serverName, actionName) {
    const client = new ROSLIB.ActionClient({ ros: this.ros, serverName, actionName });
    let open = true;
    const live = callback => value => open && !this.closed && callback(value);
    return {
      send: (goalMessage, { onStatus = () => {}, onFeedback = () => {}, onResult = () => {} } = {}) => {
        const goal = new ROSLIB.Goal({ actionClient: client, goalMessage });
        goal.on('status', live(onStatus));
        goal.on('feedback', live(onFeedback));
        goal.on('result', live(onResult));
        goal.send();
        return { id: goal.goalID, cancel: () => open && !this.closed && goal.cancel() };
      },
      close: () => {
        if (!open) return;
        open = false;
        if (!this.closed) client.dispose();
      },
    };
  }

  // A /rosapi service, e.g. rosapi('topics') or rosapi('node_details', { node: '/turtlesim' }).
  rosapi(name, args = {}) {
    return this.call(`/rosapi/${name}`, `rosapi/${name}`, args);
  }

  onStatus(listener) {
    this.ros.on('status', status => this.closed || listener(status));
  }

  close() {
    this.closed = true;
    this.topics.clear();  // (the socket is gone: the bridge already dropped them)
    for (const asked of this.fetches) asked.abort();
    this.fetches.clear();
  }
}

// The bridge serves this page and the websocket at the same address: the page's folder, path included (a reverse
// proxy may put the bridge at https://robots.example/rover1/), without its file name, query or fragment. The
// session's stream, bag and cloud addresses are relative to it.
export function bridgeUrl(loc = window.location) {
  const url = new URL('.', loc.href);
  url.protocol = loc.protocol === 'https:' ? 'wss:' : 'ws:';
  return url.href;
}
