// The page's one link to the bridge. Connection reconnects with backoff; each time it is connected it makes a
// RosSession, the only owner of ROSLIB objects, and drops it when the socket goes: subscriptions and
// advertisements live on the server side of one socket, so every panel makes its own again on the next session.
const FIRST_RETRY_MS = 500;
const MAX_RETRY_MS = 5000;
const CALL_TIMEOUT_S = 10;
const REFUSAL_MS = 500;  // a publish the bridge has not refused by then counts as published

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
    let ended = false;
    ros.on('connection', () => {
      this.everConnected = true;
      this.retryMs = FIRST_RETRY_MS;
      this.retrying = false;
      session = new RosSession(ros);
      this.onState('connected', this.url);
      this.onSession(session);
    });
    const end = () => {  // 'error' and 'close' may both fire for one failure
      if (ended) return;
      ended = true;
      ros.close();
      if (session) {
        session.close();
        this.onSession(null);
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

// One connected socket's ROS objects. Every callback it hands out is silenced once the session is closed,
// so that a late answer from a dead socket never reaches a panel that has moved on.
export class RosSession {
  constructor(ros) {
    this.ros = ros;
    this.closed = false;
    this.topics = new Set();
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
  }
}

// The bridge serves this page and the websocket on the same host, port and path.
export function bridgeUrl(loc = window.location) {
  return `${loc.protocol === 'https:' ? 'wss' : 'ws'}://${loc.host}/`;
}
