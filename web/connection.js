// The page's one link to the bridge. Connection reconnects with backoff; each time it is connected it makes a
// RosSession, the only owner of ROSLIB objects, and drops it when the socket goes: subscriptions and
// advertisements live on the server side of one socket, so every panel makes its own again on the next session.
const FIRST_RETRY_MS = 500;
const MAX_RETRY_MS = 5000;
const CALL_TIMEOUT_S = 10;

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

  // A publisher: publish(message) sends a plain object; close() unadvertises.
  advertise(name, type, options = {}) {
    const topic = new ROSLIB.Topic({ ros: this.ros, name, messageType: type, ...options });
    this.topics.add(topic);
    topic.advertise();
    return {
      publish: message => this.closed || topic.publish(new ROSLIB.Message(message)),
      close: () => {
        if (!this.topics.delete(topic) || this.closed) return;
        topic.unadvertise();
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
